// Glob patterns on '/'-separated relative paths: how batch config `match` lists pick the assets of a class.
//
//   Glob g = Glob::compile("props/**/*.{obj,stl}");
//   g.matches("props/kitchen/chair.obj");  // true
//   g.matches("props/chair.obj");          // true: "**" also matches zero segments
//
// Syntax (the pattern must match the whole path; matching is case-sensitive):
//   *       any run of characters inside one path segment (never '/')
//   ?       one character (one UTF-8 code point) other than '/'
//   [abc]   one of the listed characters; ranges [a-z]; negated [!abc] or [^abc]; ']' first is literal;
//           never matches '/'
//   {a,b}   either alternative; nestable, alternatives may be empty and may contain '/' and wildcards
//   **      only as a whole segment ("**/x", "a/**/b", "a/**"): zero or more whole segments
//   \c      the character c literally
// A pattern without '/' matches top-level paths only: "*.obj" matches "chair.obj" but not "props/chair.obj";
// write "**/*.obj" for any depth. The path is compared as given: callers pass generic ('/') relative paths.
#pragma once

#include <memory>
#include <string>
#include <string_view>

namespace lodforge::batch {

class Glob {
 public:
  // Throws std::invalid_argument whose message is the problem alone ("unclosed '['"), so that callers can
  // prefix where the pattern came from.
  static Glob compile(std::string_view pattern);

  // The problem compile() would throw for, or empty when the pattern is valid.
  static std::string problem(std::string_view pattern);

  bool matches(std::string_view relative_path) const;
  const std::string& pattern() const { return pattern_; }

 private:
  struct Compiled;
  Glob(std::string pattern, std::shared_ptr<const Compiled> compiled);

  std::string pattern_;
  std::shared_ptr<const Compiled> compiled_;  // immutable, so copies of a Glob share it
};

// Convenience for one-off matches; throws std::invalid_argument like Glob::compile.
bool glob_match(std::string_view pattern, std::string_view relative_path);

}  // namespace lodforge::batch
