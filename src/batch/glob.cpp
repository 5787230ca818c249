// Glob matching for batch config `match` lists.
//
// A pattern is compiled in two passes: brace expansion first (like the shell, so "{a,b/c}" may span segments
// and nest), then each expansion is split at '/' into segments of tokens. Matching runs the classic greedy
// wildcard algorithm with one backtrack point twice: inside a segment for '*', and over segments for '**'.
// Both are linear-times-backtracks rather than exponential, so hostile patterns such as "*a*a*a*b" stay cheap.
#include "lodforge/batch/glob.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

namespace lodforge::batch {
namespace {

// Brace expansion multiplies alternatives; a cap keeps "{a,b}{c,d}..." chains from exhausting memory.
constexpr std::size_t kMaxAlternatives = 256;

struct Token {
  enum class Kind { literal, any_char, star, char_class } kind = Kind::literal;
  char byte = 0;                                      // literal
  bool negated = false;                               // char_class
  std::vector<std::pair<char32_t, char32_t>> ranges;  // char_class, inclusive code point ranges
};

Token make_token(Token::Kind kind, char byte = 0) {
  Token t;
  t.kind = kind;
  t.byte = byte;
  return t;
}

struct Segment {
  bool any_segments = false;  // "**": zero or more whole path segments
  std::vector<Token> tokens;
};

using Alternative = std::vector<Segment>;

// Decodes one UTF-8 code point at s[i] and advances i past it. Malformed bytes decode as themselves, one byte
// each, so matching never fails on odd file names; it just treats them as opaque characters.
char32_t next_code_point(std::string_view s, std::size_t& i) {
  const auto b0 = static_cast<unsigned char>(s[i]);
  int extra = 0;  // continuation bytes after the lead byte
  if (b0 >= 0xC0 && b0 < 0xE0) extra = 1;
  if (b0 >= 0xE0 && b0 < 0xF0) extra = 2;
  if (b0 >= 0xF0 && b0 < 0xF8) extra = 3;
  if (i + extra >= s.size()) extra = 0;  // truncated at the end of the string
  char32_t cp = extra == 0 ? b0 : b0 & (0x3F >> extra);
  for (int k = 1; k <= extra; ++k) {
    const auto b = static_cast<unsigned char>(s[i + k]);
    if ((b & 0xC0) != 0x80) {  // truncated sequence: take the lead byte alone
      ++i;
      return b0;
    }
    cp = (cp << 6) | (b & 0x3F);
  }
  i += 1 + extra;
  return cp;
}

// Index one past the ']' closing the class that opens at s[open] == '['; npos when unclosed.
std::size_t class_end(std::string_view s, std::size_t open) {
  std::size_t i = open + 1;
  if (i < s.size() && (s[i] == '!' || s[i] == '^')) ++i;
  if (i < s.size() && s[i] == ']') ++i;  // "[]x]": a ']' right after the opening is a member
  while (i < s.size() && s[i] != ']') i += s[i] == '\\' ? 2 : 1;
  return i < s.size() ? i + 1 : std::string_view::npos;
}

// --- pass 1: brace expansion -----------------------------------------------------------------------------

class BraceExpander {
 public:
  explicit BraceExpander(std::string_view s) : s_(s) {}

  std::vector<std::string> expand() {
    return sequence(0);  // at depth 0 a stray '}' throws, so this consumes the whole pattern
  }

 private:
  // Expansions of the text from pos_ up to an unnested ',' or '}' (left unconsumed) or the end. Escapes and
  // character classes are copied verbatim for the tokenizer; braces and commas inside them are not syntax.
  std::vector<std::string> sequence(int depth) {
    std::vector<std::string> results{std::string{}};
    while (pos_ < s_.size()) {
      const char c = s_[pos_];
      std::size_t len = 1;
      if (c == '\\') {
        if (pos_ + 1 == s_.size()) throw std::invalid_argument("trailing '\\'");
        len = 2;
      } else if (c == '[') {
        const std::size_t end = class_end(s_, pos_);
        if (end == std::string_view::npos) throw std::invalid_argument("unclosed '['");
        len = end - pos_;
      } else if (c == '{') {
        ++pos_;
        results = product(results, group(depth + 1));
        continue;
      } else if (c == '}' || (c == ',' && depth > 0)) {
        if (depth == 0) throw std::invalid_argument("unmatched '}'");
        return results;
      }
      for (std::string& r : results) r.append(s_.substr(pos_, len));
      pos_ += len;
    }
    return results;
  }

  // The alternatives of a group whose '{' was just consumed, through its '}'.
  std::vector<std::string> group(int depth) {
    std::vector<std::string> alternatives;
    for (;;) {
      for (std::string& a : sequence(depth)) alternatives.push_back(std::move(a));
      if (alternatives.size() > kMaxAlternatives) throw too_many();
      if (pos_ == s_.size()) throw std::invalid_argument("unclosed '{'");
      if (s_[pos_++] == '}') return alternatives;  // else ',': next alternative
    }
  }

  static std::vector<std::string> product(const std::vector<std::string>& heads,
                                          const std::vector<std::string>& tails) {
    if (heads.size() * tails.size() > kMaxAlternatives) throw too_many();
    std::vector<std::string> out;
    out.reserve(heads.size() * tails.size());
    for (const std::string& h : heads) {
      for (const std::string& t : tails) out.push_back(h + t);
    }
    return out;
  }

  static std::invalid_argument too_many() {
    return std::invalid_argument("'{...}' expands to more than " + std::to_string(kMaxAlternatives) + " alternatives");
  }

  std::string_view s_;
  std::size_t pos_ = 0;
};

// --- pass 2: tokenize one expansion -----------------------------------------------------------------------

Token parse_class(std::string_view s, std::size_t open, std::size_t end) {
  Token t = make_token(Token::Kind::char_class);
  std::size_t i = open + 1;
  if (s[i] == '!' || s[i] == '^') {
    t.negated = true;
    ++i;
  }
  const std::size_t close = end - 1;
  bool first = true;
  while (i < close) {
    auto read_member = [&]() {
      if (s[i] == '\\') ++i;
      if (s[i] == '/') throw std::invalid_argument("'/' cannot appear inside '[...]'");
      return next_code_point(s, i);
    };
    // A ']' right after the opening is a member (class_end already skipped it as such).
    const char32_t lo = first && s[i] == ']' ? (++i, U']') : read_member();
    first = false;
    char32_t hi = lo;
    if (i + 1 < close && s[i] == '-') {  // a range; a '-' first or last is a literal member
      ++i;
      hi = read_member();
      if (hi < lo) throw std::invalid_argument("reversed range in '[...]'");
    }
    t.ranges.emplace_back(lo, hi);
  }
  return t;
}

Alternative tokenize(std::string_view s) {
  Alternative segments(1);
  std::size_t i = 0;
  while (i < s.size()) {
    Segment& seg = segments.back();
    const char c = s[i];
    if (c == '/') {
      if (seg.tokens.empty() && !seg.any_segments) {
        throw std::invalid_argument(i == 0 ? "must be relative (starts with '/')" : "empty path segment ('//')");
      }
      segments.emplace_back();
      ++i;
    } else if (c == '*' && i + 1 < s.size() && s[i + 1] == '*') {
      const bool alone = seg.tokens.empty() && !seg.any_segments && (i + 2 == s.size() || s[i + 2] == '/');
      if (!alone) throw std::invalid_argument("'**' must be a whole path segment (\"**/x\", \"a/**\")");
      seg.any_segments = true;
      i += 2;
    } else if (c == '*') {
      seg.tokens.push_back(make_token(Token::Kind::star));
      ++i;
    } else if (c == '?') {
      seg.tokens.push_back(make_token(Token::Kind::any_char));
      ++i;
    } else if (c == '[') {
      const std::size_t end = class_end(s, i);  // closed: brace expansion checked
      seg.tokens.push_back(parse_class(s, i, end));
      i = end;
    } else {
      if (c == '\\') ++i;  // escape: next byte is literal (trailing '\' was rejected by brace expansion)
      seg.tokens.push_back(make_token(Token::Kind::literal, s[i]));
      ++i;
    }
  }
  if (segments.back().tokens.empty() && !segments.back().any_segments) {
    throw std::invalid_argument(segments.size() == 1 ? "empty pattern" : "ends with '/'");
  }
  for (const Segment& seg : segments) {
    const bool dots = seg.tokens.size() <= 2 && !seg.tokens.empty() &&
                      std::all_of(seg.tokens.begin(), seg.tokens.end(),
                                  [](const Token& t) { return t.kind == Token::Kind::literal && t.byte == '.'; });
    if (dots) throw std::invalid_argument("'.' and '..' segments are not allowed");
  }
  return segments;
}

// --- matching --------------------------------------------------------------------------------------------

// Whether token t (not a star) matches at s[i]; on success i moves past the matched character.
bool match_token(const Token& t, std::string_view s, std::size_t& i) {
  switch (t.kind) {
    case Token::Kind::literal:
      if (s[i] != t.byte) return false;
      ++i;
      return true;
    case Token::Kind::any_char:
      next_code_point(s, i);
      return true;
    case Token::Kind::char_class: {
      const char32_t cp = next_code_point(s, i);
      bool in = false;
      for (const auto& [lo, hi] : t.ranges) in = in || (lo <= cp && cp <= hi);
      return in != t.negated;
    }
    case Token::Kind::star:
      break;
  }
  return false;
}

// Greedy match with one backtrack point: on a mismatch, the latest '*' absorbs one more character. Path
// segments contain no '/', so '*' and '?' never cross a segment here.
bool match_segment(const std::vector<Token>& tokens, std::string_view s) {
  std::size_t t = 0, i = 0;
  std::size_t star_t = std::string_view::npos, star_i = 0;
  while (i < s.size()) {
    if (t < tokens.size() && tokens[t].kind == Token::Kind::star) {
      star_t = t++;
      star_i = i;
      continue;
    }
    std::size_t next = i;
    if (t < tokens.size() && match_token(tokens[t], s, next)) {
      ++t;
      i = next;
      continue;
    }
    if (star_t == std::string_view::npos) return false;
    t = star_t + 1;
    next_code_point(s, star_i);  // the star takes one more whole character
    i = star_i;
  }
  while (t < tokens.size() && tokens[t].kind == Token::Kind::star) ++t;
  return t == tokens.size();
}

// The same algorithm one level up: '**' segments are the stars, path segments the characters.
bool match_alternative(const Alternative& pattern, const std::vector<std::string_view>& path) {
  std::size_t p = 0, i = 0;
  std::size_t star_p = std::string_view::npos, star_i = 0;
  while (i < path.size()) {
    if (p < pattern.size() && pattern[p].any_segments) {
      star_p = p++;
      star_i = i;
      continue;
    }
    if (p < pattern.size() && match_segment(pattern[p].tokens, path[i])) {
      ++p;
      ++i;
      continue;
    }
    if (star_p == std::string_view::npos) return false;
    p = star_p + 1;
    i = ++star_i;
  }
  while (p < pattern.size() && pattern[p].any_segments) ++p;
  return p == pattern.size();
}

}  // namespace

struct Glob::Compiled {
  std::vector<Alternative> alternatives;
};

Glob::Glob(std::string pattern, std::shared_ptr<const Compiled> compiled)
    : pattern_(std::move(pattern)), compiled_(std::move(compiled)) {}

Glob Glob::compile(std::string_view pattern) {
  if (pattern.empty()) throw std::invalid_argument("empty pattern");
  auto compiled = std::make_shared<Compiled>();
  for (const std::string& expansion : BraceExpander(pattern).expand()) {
    compiled->alternatives.push_back(tokenize(expansion));
  }
  return Glob(std::string(pattern), std::move(compiled));
}

std::string Glob::problem(std::string_view pattern) {
  try {
    compile(pattern);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return {};
}

bool Glob::matches(std::string_view relative_path) const {
  std::vector<std::string_view> segments;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= relative_path.size(); ++i) {
    if (i == relative_path.size() || relative_path[i] == '/') {
      segments.push_back(relative_path.substr(start, i - start));
      start = i + 1;
    }
  }
  for (const Alternative& a : compiled_->alternatives) {
    if (match_alternative(a, segments)) return true;
  }
  return false;
}

bool glob_match(std::string_view pattern, std::string_view relative_path) {
  return Glob::compile(pattern).matches(relative_path);
}

}  // namespace lodforge::batch
