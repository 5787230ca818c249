// report.html: the batch report as one self-contained page.
//
// The page has to stay usable for libraries of 100 000 assets, so the table is not markup: the report is reduced
// to compact columnar JSON in the page, and a small script draws one page of rows at a time, filters, sorts and
// expands rows. The pipeline:
//   read_assets      the document's "assets" array -> a typed model; anything missing or malformed is "absent"
//   order_assets     one row per asset, worst first (the data's order; the script's default)
//   render_*         one function per page section, each appending to the page
// The small, bounded sections (header, changes, failures, worst assets, config) are rendered here as HTML/SVG.
#include "lodforge/batch/report_html.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "lodforge/batch/runner.hpp"

namespace lodforge::batch {
namespace {

using nlohmann::json;

constexpr std::string_view kDash = "\xE2\x80\x93";         // "–" (U+2013): what absent values show
constexpr std::string_view kReplacement = "\xEF\xBF\xBD";  // U+FFFD: stands in for bytes HTML can't carry
constexpr std::string_view kEllipsis = "\xE2\x80\xA6";     // "…"
constexpr std::string_view kNarrowSpace = "\xE2\x80\xAF";  // digit grouping in counts: "1 234 567"
constexpr std::size_t kWorstAssets = 10;                   // bars in the worst-assets chart
constexpr std::size_t kBarLabelCodePoints = 40;            // longer paths keep their tail (the file name)
constexpr std::size_t kProblemRows = 200;                  // failed or skipped assets listed in full above the table

// ---------------------------------------------------------------------------------------------------------------
// Text: escaping and number formatting. Both are byte-exact and locale-independent (std::to_chars), which is what
// makes the page deterministic.

// Length of the valid UTF-8 sequence at s[i], or 0 when the bytes there are not one (stray continuation byte,
// truncated or overlong sequence, surrogate, beyond U+10FFFF).
std::size_t utf8_sequence_length(std::string_view s, std::size_t i) {
  const auto b0 = static_cast<unsigned char>(s[i]);
  std::size_t length = 0;
  char32_t cp = 0;
  if (b0 < 0x80) return 1;
  if (b0 >= 0xC2 && b0 <= 0xDF) {
    length = 2, cp = b0 & 0x1F;
  } else if (b0 >= 0xE0 && b0 <= 0xEF) {
    length = 3, cp = b0 & 0x0F;
  } else if (b0 >= 0xF0 && b0 <= 0xF4) {
    length = 4, cp = b0 & 0x07;
  } else {
    return 0;  // continuation byte, or a lead byte that can only start an overlong or out-of-range sequence
  }
  if (i + length > s.size()) return 0;
  for (std::size_t k = 1; k < length; ++k) {
    const auto b = static_cast<unsigned char>(s[i + k]);
    if ((b & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (b & 0x3F);
  }
  const bool overlong = (length == 3 && cp < 0x800) || (length == 4 && cp < 0x10000);
  const bool surrogate = cp >= 0xD800 && cp <= 0xDFFF;
  if (overlong || surrogate || cp > 0x10FFFF) return 0;
  return length;
}

// The character reference for the characters that are markup in text or in quoted attribute values; empty for
// all others.
std::string_view entity(char c) {
  switch (c) {
    case '&':
      return "&amp;";
    case '<':
      return "&lt;";
    case '>':
      return "&gt;";
    case '"':
      return "&quot;";
    case '\'':
      return "&#39;";
    default:
      return {};
  }
}

// Appends `s` as HTML text, safe both in element content and in double- or single-quoted attribute values.
void append_escaped(std::string& out, std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const char c = s[i];
    if (const std::string_view e = entity(c); !e.empty()) {
      out += e;
      ++i;
      continue;
    }
    const auto b = static_cast<unsigned char>(c);
    if ((b < 0x20 && c != '\t' && c != '\n' && c != '\r') || b == 0x7F) {  // C0 controls and DEL
      out += kReplacement;
      ++i;
      continue;
    }
    const std::size_t length = utf8_sequence_length(s, i);
    if (length == 0) {  // one bad byte becomes one replacement character; resynchronise at the next byte
      out += kReplacement;
      ++i;
      continue;
    }
    if (length == 2 && b == 0xC2 && static_cast<unsigned char>(s[i + 1]) <= 0x9F) {  // C1 controls, U+0080..9F
      out += kReplacement;
      i += 2;
      continue;
    }
    out.append(s.substr(i, length));
    i += length;
  }
}

// Whether `s` is valid UTF-8 without control characters: text that reaches the page unchanged.
bool clean_text(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto b = static_cast<unsigned char>(s[i]);
    const std::size_t length = utf8_sequence_length(s, i);
    if (length == 0 || b < 0x20 || b == 0x7F || (length == 2 && b == 0xC2 && static_cast<unsigned char>(s[i + 1]) <= 0x9F)) {
      return false;
    }
    i += length;
  }
  return true;
}

std::string escaped(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  append_escaped(out, s);
  return out;
}

// The last `max_code_points` code points of `s`, led by "…" when shortened; cut on a code point boundary.
std::string tail_ellipsized(std::string_view s, std::size_t max_code_points) {
  std::size_t code_points = 0;
  for (const char c : s) code_points += (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  if (code_points <= max_code_points) return std::string(s);
  std::size_t skip = code_points - (max_code_points - 1);  // code points to drop; one slot goes to the ellipsis
  std::size_t i = 0;
  for (; i < s.size(); ++i) {
    if ((static_cast<unsigned char>(s[i]) & 0xC0) != 0x80 && skip-- == 0) break;
  }
  return std::string(kEllipsis) + std::string(s.substr(i));
}

std::string trim_negative_zero(std::string s) {
  if (!s.empty() && s[0] == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);
  return s;
}

// `v` with exactly `decimals` digits after the point ("0.2500"); "–" when not finite (a finite value scaled to
// percent can overflow).
std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return std::string(kDash);
  std::array<char, 400> buf{};  // the largest double in fixed notation has 309 integer digits
  auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::fixed, decimals);
  if (r.ec != std::errc{}) r = std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::scientific, 3);
  return trim_negative_zero(std::string(buf.data(), r.ptr));
}

// Whole numbers as integers, others with six significant digits: target values (0.25, 5000, 0.005).
std::string compact(double v) {
  if (std::abs(v) < 1e15 && v == std::floor(v)) return fixed(v, 0);
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v, std::chars_format::general, 6);
  return trim_negative_zero(std::string(buf.data(), r.ptr));
}

// Counts rounded to integers and grouped by threes: "1 234 567".
std::string count(double v) {
  std::string digits = fixed(std::round(v), 0);
  const std::size_t sign = !digits.empty() && digits[0] == '-';
  if (digits.find_first_not_of("-0123456789") != std::string::npos) return digits;  // scientific fallback
  std::string out = digits.substr(0, sign);
  const std::size_t n = digits.size() - sign;
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0 && (n - k) % 3 == 0) out += kNarrowSpace;
    out += digits[sign + k];
  }
  return out;
}

// ---------------------------------------------------------------------------------------------------------------
// Reading the document. Every accessor returns "absent" for missing keys, nulls, wrong types and non-finite
// numbers (a report built in memory can hold NaN; one parsed from report.json has null there), so no access
// below can throw.

const json* field(const json& object, const char* key) {
  if (!object.is_object()) return nullptr;
  const auto it = object.find(key);
  if (it == object.end() || it->is_null()) return nullptr;
  return &*it;
}

std::optional<double> number(const json& object, const char* key) {
  const json* v = field(object, key);
  if (v == nullptr || !v->is_number()) return std::nullopt;
  const double d = v->get<double>();
  if (!std::isfinite(d)) return std::nullopt;
  return d;
}

std::optional<std::int64_t> integer(const json& object, const char* key) {
  const std::optional<double> d = number(object, key);
  if (!d || std::abs(*d) > 9e15) return std::nullopt;  // beyond that a double no longer holds every integer
  return static_cast<std::int64_t>(std::llround(*d));
}

std::optional<std::string> text(const json& object, const char* key) {
  const json* v = field(object, key);
  if (v == nullptr || !v->is_string()) return std::nullopt;
  return v->get<std::string>();
}

std::optional<bool> flag(const json& object, const char* key) {
  const json* v = field(object, key);
  if (v == nullptr || !v->is_boolean()) return std::nullopt;
  return v->get<bool>();
}

const json& member(const json& object, const char* key) {
  static const json kNull;  // immutable: not state, just the "absent" value to return by reference
  const json* v = field(object, key);
  return v != nullptr ? *v : kNull;
}

struct Lod {
  std::optional<std::int64_t> level;
  std::optional<std::string> target_kind;
  std::optional<double> target_value;
  std::optional<double> target_triangles;
  std::optional<double> triangles;
  std::optional<double> ratio;  // achieved triangles / source triangles
  std::optional<double> error_bound_rel;
  std::optional<double> mean_rel;  // measured errors, as fractions of the source's bounding-box diagonal
  std::optional<double> rms_rel;
  std::optional<double> hausdorff_rel;
  std::optional<double> normal_deviation_mean_deg;
  std::optional<double> uv_problems;    // UV-flipped plus chart-spanning triangles (attributes), absent without UVs
  std::optional<double> quad_fraction;  // quads / faces of the LOD
  std::optional<std::string> stop_reason;
  std::optional<double> seconds;
  std::optional<double> screen_coverage;
  std::optional<std::string> budget;  // "met", or "missed: " and the reasons
  bool missed() const { return budget && budget->starts_with("missed"); }
};

// A collision or occluder LOD (report.json "conservative_lods"): an output beside the chain, shown in its own table.
struct Separate {
  std::optional<std::string> kind;    // "collision" | "occluder"
  std::optional<std::string> target;  // "ratio 0.1"
  std::optional<double> triangles;
  std::optional<double> hausdorff_rel;
  std::optional<double> volume_change_pct;
  std::optional<std::string> budget;  // "met", or "missed: " and the reasons
  std::string where;                  // its files, or its glTF node suffix
  bool missed() const { return budget && budget->starts_with("missed"); }
};

struct Asset {
  std::optional<std::string> path;
  std::optional<std::string> class_name;  // absent: no class matched
  std::optional<std::string> status;
  std::optional<std::string> error;
  std::optional<bool> cache_hit;
  std::optional<double> seconds;
  std::vector<Lod> lods;
  std::vector<Separate> separate;
  std::optional<double> max_hausdorff_rel;  // over the LODs: the asset's worst measured error
  std::optional<double> input_triangles;
  std::optional<double> input_bytes;   // the source's mesh data on disk
  std::optional<double> output_bytes;  // everything written for the asset
  std::size_t pictures = 0;            // LOD pictures beside the report, source first (picture_file_name)
  bool missed() const {
    return std::any_of(lods.begin(), lods.end(), [](const Lod& l) { return l.missed(); }) ||
           std::any_of(separate.begin(), separate.end(), [](const Separate& l) { return l.missed(); });
  }

  bool failed() const { return status == "failed"; }
  std::string_view path_or_empty() const { return path ? std::string_view(*path) : std::string_view(); }
};

// "met", or "missed: " and the reasons, from a record's "budget".
std::optional<std::string> budget_text(const json& budget) {
  const std::optional<std::string> status = text(budget, "status");
  if (!status) return std::nullopt;
  std::string b = *status;
  const json& reasons = member(budget, "reasons");
  if (reasons.is_array()) {
    for (const json& r : reasons) {
      if (r.is_string()) b += (b == *status ? ": " : "; ") + r.get<std::string>();
    }
  }
  return b;
}

Separate read_separate(const json& j) {
  Separate c;
  c.kind = text(j, "kind");
  const json& target = member(j, "target");
  const std::optional<std::string> kind = text(target, "kind");
  const std::optional<double> value = number(target, "value");
  if (kind || value) c.target = kind.value_or(std::string(kDash)) + ' ' + (value ? compact(*value) : std::string(kDash));
  c.triangles = number(j, "triangles");
  c.hausdorff_rel = number(j, "hausdorff_rel");
  c.volume_change_pct = number(j, "volume_change_pct");
  c.budget = budget_text(member(j, "budget"));
  const json& outputs = member(j, "outputs");
  if (outputs.is_array()) {
    for (const json& o : outputs) {
      if (o.is_string()) c.where += (c.where.empty() ? "" : ", ") + o.get<std::string>();
    }
  }
  if (const std::optional<std::string> suffix = text(j, "gltf_node_suffix")) {
    c.where += (c.where.empty() ? "" : "; ") + std::string("glTF nodes *") + *suffix;
  }
  return c;
}

Lod read_lod(const json& j) {
  Lod lod;
  lod.level = integer(j, "level");
  const json& target = member(j, "target");
  lod.target_kind = text(target, "kind");
  lod.target_value = number(target, "value");
  lod.target_triangles = number(j, "target_triangles");
  lod.triangles = number(j, "triangles");
  lod.ratio = number(j, "ratio");
  lod.error_bound_rel = number(j, "error_bound_rel");
  lod.mean_rel = number(j, "mean_rel");
  lod.rms_rel = number(j, "rms_rel");
  lod.hausdorff_rel = number(j, "hausdorff_rel");
  lod.normal_deviation_mean_deg = number(j, "normal_deviation_mean_deg");
  const json& attributes = member(j, "attributes");
  const std::optional<double> flipped = number(attributes, "uv_flipped"), spanning = number(attributes, "uv_spanning");
  if (flipped && spanning) lod.uv_problems = *flipped + *spanning;
  lod.quad_fraction = number(j, "quad_fraction");
  lod.stop_reason = text(j, "stop_reason");
  lod.seconds = number(j, "seconds");
  lod.screen_coverage = number(j, "screen_coverage");
  lod.budget = budget_text(member(j, "budget"));
  return lod;
}

// Non-object entries of "assets" or "lods" are not records of anything and are dropped.
std::vector<Asset> read_assets(const json& report) {
  std::vector<Asset> assets;
  const json& list = member(report, "assets");
  if (!list.is_array()) return assets;
  for (const json& j : list) {
    if (!j.is_object()) continue;
    Asset a;
    a.path = text(j, "path");
    a.class_name = text(j, "class");
    a.status = text(j, "status");
    a.error = text(j, "error");
    a.cache_hit = flag(j, "cache_hit");
    a.seconds = number(j, "seconds");
    a.input_triangles = number(member(j, "input"), "triangles");
    a.input_bytes = number(member(j, "input"), "bytes");
    a.output_bytes = number(j, "output_bytes");
    // Pictures are listed only under the names the page derives from the path (which must reach the page
    // unchanged), so it can never link elsewhere.
    if (const json& pictures = member(j, "pictures"); pictures.is_array() && a.path && clean_text(*a.path)) {
      while (a.pictures < pictures.size() && pictures[a.pictures].is_string() &&
             pictures[a.pictures].get<std::string>() == picture_file_name(*a.path, a.pictures)) {
        ++a.pictures;
      }
      if (a.pictures < pictures.size()) a.pictures = 0;
    }
    if (const json& separate = member(j, "conservative_lods"); separate.is_array()) {
      for (const json& c : separate) {
        if (c.is_object()) a.separate.push_back(read_separate(c));
      }
    }
    const json& lods = member(j, "lods");
    if (lods.is_array()) {
      for (const json& l : lods) {
        if (!l.is_object()) continue;
        a.lods.push_back(read_lod(l));
        const std::optional<double> h = a.lods.back().hausdorff_rel;
        if (h && (!a.max_hausdorff_rel || *h > *a.max_hausdorff_rel)) a.max_hausdorff_rel = h;
      }
    }
    assets.push_back(std::move(a));
  }
  return assets;
}
// ---------------------------------------------------------------------------------------------------------------
// Order: one row per asset, worst first.

// Failed assets on top (they have no error to compare), then assets with a LOD that missed its budget, then by
// the largest Hausdorff distance over their LODs, unmeasured last; ties by path, then document order.
std::vector<const Asset*> order_assets(const std::vector<Asset>& assets) {
  std::vector<const Asset*> order;
  order.reserve(assets.size());
  for (const Asset& a : assets) order.push_back(&a);
  std::stable_sort(order.begin(), order.end(), [](const Asset* x, const Asset* y) {
    if (x->failed() != y->failed()) return x->failed();
    if (x->missed() != y->missed()) return x->missed();
    const std::optional<double> hx = x->max_hausdorff_rel, hy = y->max_hausdorff_rel;
    if (hx.has_value() != hy.has_value()) return hx.has_value();
    if (hx && *hx != *hy) return *hx > *hy;
    return x->path_or_empty() < y->path_or_empty();
  });
  return order;
}

// ---------------------------------------------------------------------------------------------------------------
// The page's data: the report reduced to what the table and plots show, as compact columnar JSON inside a
// non-executed <script type="application/json"> block (a file next to the page cannot be read from file://).
// Floats keep four significant digits, which is what the page displays; strings that repeat (directories,
// classes, targets, stop reasons, budget reasons) are listed once and referred to by index.

// A JSON number with 4 significant digits (or an integer), or null when absent.
void append_number(std::string& out, const std::optional<double>& v) {
  if (!v) {
    out += "null";
    return;
  }
  if (std::abs(*v) < 1e15 && *v == std::floor(*v)) {
    out += fixed(*v, 0);
    return;
  }
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), *v, std::chars_format::general, 4);
  std::string s(buf.data(), r.ptr);
  if (s.find_first_of("eE") != std::string::npos) {  // "1.5e-05" is valid JSON; strip a redundant "+"
    const std::size_t plus = s.find('+');
    if (plus != std::string::npos) s.erase(plus, 1);
  }
  out += trim_negative_zero(s);
}

// A JSON string: the same replacement of bytes HTML cannot carry as everywhere else, JSON-escaped, and "<"
// written as \u003c so that no "</script" can end the data block early.
void append_json_string(std::string& out, std::string_view s) {
  std::string clean;
  clean.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    const auto b = static_cast<unsigned char>(s[i]);
    if ((b < 0x20 && s[i] != '\t' && s[i] != '\n' && s[i] != '\r') || b == 0x7F) {
      clean += kReplacement;
      ++i;
      continue;
    }
    const std::size_t length = utf8_sequence_length(s, i);
    if (length == 0 || (length == 2 && b == 0xC2 && static_cast<unsigned char>(s[i + 1]) <= 0x9F)) {
      clean += kReplacement;
      i += length == 0 ? 1 : 2;
      continue;
    }
    clean.append(s.substr(i, length));
    i += length;
  }
  const std::string dumped = json(clean).dump();
  for (const char c : dumped) {
    if (c == '<') {
      out += "\\u003c";
    } else if (c == '>') {
      out += "\\u003e";
    } else if (c == '&') {
      out += "\\u0026";
    } else {
      out += c;
    }
  }
}

// Strings listed once: index by first appearance, so the same document gives the same table.
class StringTable {
 public:
  int index(const std::string& s) {
    const auto [it, inserted] = ids_.emplace(s, static_cast<int>(list_.size()));
    if (inserted) list_.push_back(s);
    return it->second;
  }
  int index(const std::optional<std::string>& s) { return s ? index(*s) : -1; }
  void append(std::string& out) const {
    out += '[';
    for (std::size_t i = 0; i < list_.size(); ++i) {
      if (i > 0) out += ',';
      append_json_string(out, list_[i]);
    }
    out += ']';
  }

 private:
  std::map<std::string, int> ids_;
  std::vector<std::string> list_;
};

template <class T, class Get>
void column(std::string& out, std::string_view name, const std::vector<T>& items, Get get) {
  out += '"';
  out += name;
  out += "\":[";
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) out += ',';
    get(out, items[i]);
  }
  out += "],\n";
}

int status_code(const std::optional<std::string>& status) {
  if (status == "ok") return 0;
  if (status == "failed") return 1;
  if (status == "skipped") return 2;
  if (status == "not_started") return 3;
  return 4;
}

std::optional<double> percent_of(const std::optional<double>& fraction) {
  if (!fraction || !std::isfinite(*fraction * 100.0)) return std::nullopt;
  return *fraction * 100.0;
}

// The smallest positive value and the largest value over `values`; nullopt when none is positive.
struct Range {
  std::optional<double> lo, hi;
  void add(const std::optional<double>& v) {
    if (!v || !(*v > 0) || *v > 1e280) return;
    if (!lo || *v < *lo) lo = *v;
    if (!hi || *v > *hi) hi = *v;
  }
};

void render_data(std::string& out, const std::vector<const Asset*>& order) {
  StringTable dirs, classes, targets, stops, reasons;
  struct Flat {
    const Asset* asset;
    const Lod* lod;
  };
  std::vector<Flat> lods;
  Range triangles, errors;
  for (const Asset* a : order) {
    for (const Lod& l : a->lods) {
      lods.push_back({a, &l});
      triangles.add(l.triangles);
      errors.add(percent_of(l.hausdorff_rel));
      errors.add(percent_of(l.mean_rel));
    }
    triangles.add(a->input_triangles);
  }
  std::vector<int> dir_ids, class_ids;
  std::vector<std::string> names;
  for (const Asset* a : order) {
    const std::string_view path = a->path_or_empty();
    const std::size_t slash = path.rfind('/');
    const std::string dir = slash == std::string_view::npos ? std::string() : std::string(path.substr(0, slash + 1));
    dir_ids.push_back(a->path ? dirs.index(dir) : -1);
    names.push_back(std::string(slash == std::string_view::npos ? path : path.substr(slash + 1)));
    class_ids.push_back(classes.index(a->class_name));
  }
  std::vector<int> target_ids, stop_ids, reason_ids;
  for (const Flat& f : lods) {
    std::optional<std::string> target;
    if (f.lod->target_kind || f.lod->target_value) {
      target = f.lod->target_kind.value_or(std::string(kDash)) + ' ' +
               (f.lod->target_value ? compact(*f.lod->target_value) : std::string(kDash));
    }
    target_ids.push_back(targets.index(target));
    stop_ids.push_back(stops.index(f.lod->stop_reason));
    std::optional<std::string> why;
    if (f.lod->budget) {
      const std::size_t colon = f.lod->budget->find(": ");
      if (colon != std::string::npos) why = f.lod->budget->substr(colon + 2);
    }
    reason_ids.push_back(reasons.index(why));
  }

  out += "<script type=\"application/json\" id=\"report-data\">{\n";
  std::size_t i = 0;
  column(out, "dir", order, [&](std::string& o, const Asset*) { o += std::to_string(dir_ids[i++]); });
  column(out, "name", names, [&](std::string& o, const std::string& n) { append_json_string(o, n); });
  i = 0;
  column(out, "cls", order, [&](std::string& o, const Asset*) { o += std::to_string(class_ids[i++]); });
  // Each asset's place in path order, so that sorting by path in the page compares numbers, not strings.
  std::vector<std::size_t> by_path(order.size()), path_rank(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) by_path[k] = k;
  std::stable_sort(by_path.begin(), by_path.end(), [&](std::size_t x, std::size_t y) {
    return order[x]->path_or_empty() < order[y]->path_or_empty();
  });
  for (std::size_t k = 0; k < by_path.size(); ++k) path_rank[by_path[k]] = k;
  column(out, "pr", path_rank, [](std::string& o, std::size_t r) { o += std::to_string(r); });
  column(out, "st", order, [](std::string& o, const Asset* a) { o += std::to_string(status_code(a->status)); });
  column(out, "hit", order, [](std::string& o, const Asset* a) {
    o += a->cache_hit ? (*a->cache_hit ? "1" : "0") : "null";
  });
  column(out, "itri", order, [](std::string& o, const Asset* a) { append_number(o, a->input_triangles); });
  column(out, "ib", order, [](std::string& o, const Asset* a) { append_number(o, a->input_bytes); });
  column(out, "ob", order, [](std::string& o, const Asset* a) { append_number(o, a->output_bytes); });
  column(out, "nl", order, [](std::string& o, const Asset* a) { o += std::to_string(a->lods.size()); });
  column(out, "pic", order, [](std::string& o, const Asset* a) { o += std::to_string(a->pictures); });
  // Errors of assets that did not finish: sparse, most assets have none.
  out += "\"err\":{";
  bool first = true;
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (!order[k]->error) continue;
    out += first ? "" : ",";
    first = false;
    out += '"' + std::to_string(k) + "\":";
    append_json_string(out, *order[k]->error);
  }
  out += "},\n";
  // Collision and occluder LODs, sparse too: [kind, target, triangles, Hausdorff %, volume change %, budget met,
  // reasons, where] per entry.
  out += "\"cons\":{";
  first = true;
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (order[k]->separate.empty()) continue;
    out += first ? "" : ",";
    first = false;
    out += '"' + std::to_string(k) + "\":[";
    for (std::size_t e = 0; e < order[k]->separate.size(); ++e) {
      const Separate& c = order[k]->separate[e];
      out += e ? ",[" : "[";
      append_json_string(out, c.kind.value_or(std::string(kDash)));
      out += ',';
      append_json_string(out, c.target.value_or(std::string(kDash)));
      out += ',';
      append_number(out, c.triangles);
      out += ',';
      append_number(out, percent_of(c.hausdorff_rel));
      out += ',';
      append_number(out, c.volume_change_pct);
      out += !c.budget ? ",null," : c.missed() ? ",0," : ",1,";
      const std::size_t colon = c.budget ? c.budget->find(": ") : std::string::npos;
      if (colon == std::string::npos) {
        out += "null";
      } else {
        append_json_string(out, c.budget->substr(colon + 2));
      }
      out += ',';
      append_json_string(out, c.where);
      out += ']';
    }
    out += ']';
  }
  out += "},\n";
  column(out, "lv", lods, [](std::string& o, const Flat& f) {
    append_number(o, f.lod->level ? std::optional<double>(static_cast<double>(*f.lod->level)) : std::nullopt);
  });
  i = 0;
  column(out, "tgt", lods, [&](std::string& o, const Flat&) { o += std::to_string(target_ids[i++]); });
  column(out, "ttri", lods, [](std::string& o, const Flat& f) { append_number(o, f.lod->target_triangles); });
  column(out, "tri", lods, [](std::string& o, const Flat& f) { append_number(o, f.lod->triangles); });
  column(out, "eb", lods, [](std::string& o, const Flat& f) { append_number(o, percent_of(f.lod->error_bound_rel)); });
  column(out, "mean", lods, [](std::string& o, const Flat& f) { append_number(o, percent_of(f.lod->mean_rel)); });
  column(out, "h", lods, [](std::string& o, const Flat& f) { append_number(o, percent_of(f.lod->hausdorff_rel)); });
  column(out, "sc", lods, [](std::string& o, const Flat& f) { append_number(o, f.lod->screen_coverage); });
  column(out, "bud", lods, [](std::string& o, const Flat& f) {
    o += !f.lod->budget ? "null" : f.lod->missed() ? "0" : "1";
  });
  i = 0;
  column(out, "why", lods, [&](std::string& o, const Flat&) { o += std::to_string(reason_ids[i++]); });
  i = 0;
  column(out, "stop", lods, [&](std::string& o, const Flat&) { o += std::to_string(stop_ids[i++]); });
  out += "\"dirs\":";
  dirs.append(out);
  out += ",\n\"classes\":";
  classes.append(out);
  out += ",\n\"targets\":";
  targets.append(out);
  out += ",\n\"stops\":";
  stops.append(out);
  out += ",\n\"reasons\":";
  reasons.append(out);
  out += ",\n\"picdir\":";
  append_json_string(out, std::string(kPictureFolder) + "/");
  // One pair of axes for every plot: the whole report's triangle and error ranges.
  out += ",\n\"axes\":{\"tri\":[";
  append_number(out, triangles.lo);
  out += ',';
  append_number(out, triangles.hi);
  out += "],\"err\":[";
  append_number(out, errors.lo);
  out += ',';
  append_number(out, errors.hi);
  out += "]}\n}</script>\n";
}

// ---------------------------------------------------------------------------------------------------------------
// Page sections. Each appends to `out`; text from the document goes through append_escaped, always.

constexpr std::string_view kStyle = R"css(
:root { color-scheme: light; --fg: #1d1f23; --muted: #5f6670; --line: #d8dce2; --head: #f2f4f7; --bad: #b3261e; }
* { box-sizing: border-box; }
body { margin: 0 auto; max-width: 1500px; padding: 16px 24px 48px; font: 14px/1.45 system-ui, -apple-system,
  "Segoe UI", Roboto, sans-serif; color: var(--fg); background: #fff; }
h1 { font-size: 22px; margin: 0 0 4px; }
h2 { font-size: 17px; margin: 28px 0 8px; border-bottom: 1px solid var(--line); padding-bottom: 4px; }
.meta { color: var(--muted); margin: 0 0 12px; }
.meta span { margin-right: 18px; white-space: nowrap; }
.meta b { color: var(--fg); font-weight: 600; }
.figures { display: flex; flex-wrap: wrap; gap: 8px; margin: 8px 0; }
.figure { border: 1px solid var(--line); border-radius: 6px; padding: 6px 12px; min-width: 110px; }
.figure .v { font-size: 18px; font-weight: 600; font-variant-numeric: tabular-nums; }
.figure .k { color: var(--muted); font-size: 12px; }
.figure.bad .v { color: var(--bad); }
.empty { font-style: italic; color: var(--muted); }
.scroll { overflow: auto; max-height: 85vh; }  /* a box of its own, so the sticky header row stays in view */
table { border-collapse: collapse; font-size: 13px; }
th, td { border-bottom: 1px solid var(--line); padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: var(--head); position: sticky; top: 0; cursor: pointer; user-select: none; white-space: nowrap; }
th:focus-visible { outline: 2px solid #4e79a7; outline-offset: -2px; }
th::after { content: " \2195"; opacity: 0.3; }
th[aria-sort="ascending"]::after { content: " \25B2"; opacity: 1; }
th[aria-sort="descending"]::after { content: " \25BC"; opacity: 1; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.na { color: var(--muted); }
td.err { white-space: pre-wrap; word-break: break-word; }
tr.failed td { background: #fdecea; }
.st-failed { color: var(--bad); font-weight: 600; }
.st-skipped { color: var(--muted); }
.plots { display: flex; flex-wrap: wrap; gap: 16px; }
figure { margin: 0; }
figcaption { font-weight: 600; margin-bottom: 4px; }
figcaption small { font-weight: normal; color: var(--muted); }
svg { display: block; max-width: 100%; height: auto; background: #fff; }
svg text { font: 11px system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; fill: #1d1f23; }
svg .grid { stroke: #e6e9ee; stroke-width: 1; }
svg .minor { stroke: #f1f3f6; stroke-width: 1; }
svg .frame { fill: none; stroke: #9aa1ab; stroke-width: 1; }
svg .muted { fill: #5f6670; }
.controls { margin: 8px 0; display: flex; gap: 8px; align-items: center; flex-wrap: wrap; }
.controls input { min-width: 22em; padding: 3px 6px; }
td.path { overflow-wrap: anywhere; min-width: 22em; }
th:empty::after { content: none; }
#assets td { white-space: nowrap; }
#assets td.path { white-space: normal; }
td.path .dir { color: var(--muted); }
td.path .file { font-weight: 600; }
tr.missed td { background: #fff6e5; }
tr.expanded > td { background: #fafbfc; }
button.toggle { border: 0; background: none; cursor: pointer; font-size: 13px; padding: 0 4px; }
.detail { display: flex; gap: 16px; align-items: flex-start; flex-wrap: wrap; }
table.lods th, table.separate th { position: static; cursor: default; }
table.lods th::after, table.separate th::after { content: none; }
table.separate { margin-top: 8px; }
svg.chain { background: #fff; border: 1px solid var(--line); }
svg.chain polyline { fill: none; stroke-width: 1.5; }
svg.chain polyline.haus { stroke: #e15759; }
svg.chain polyline.mean { stroke: #4e79a7; stroke-dasharray: 4 3; }
svg.chain circle.haus { fill: #e15759; }
svg.chain circle.mean { fill: #4e79a7; }
.pics { display: flex; gap: 8px; flex-wrap: wrap; }
.pics img { display: block; width: 160px; height: 160px; border: 1px solid var(--line); background: #fff; }
.pics figcaption { font-weight: normal; font-size: 12px; color: var(--muted); }
#overview-legend .key { margin-right: 14px; white-space: nowrap; }
canvas.overview { display: block; border: 1px solid var(--line); background: #fff; }
.muted { color: var(--muted); }
pre { background: var(--head); padding: 8px 12px; overflow-x: auto; font-size: 12px; }
)css";


// The assets table, drawn by the page from the data block: one row per asset, 50 to a page (a redraw costs what
// its rows cost), filtered by search text, class and status, sorted by any column (ties keep the worst-first
// rank). A row expands to its LODs and a plot of error against triangles, the chain from the source connected,
// on the report's shared log axes (errors of zero sit on a row of their own below the lowest decade).
constexpr std::string_view kScript = R"js(
(function () {
  "use strict";
  var el = document.getElementById("report-data");
  if (!el) return;
  var D = JSON.parse(el.textContent), n = D.st.length, PAGE = 50;
  var STATUS = ["ok", "failed", "skipped", "not started", "?"];
  var off = new Int32Array(n + 1), worst = new Float64Array(n), missed = new Uint8Array(n), low = new Array(n);
  var i, k;
  for (i = 0; i < n; i++) {
    off[i + 1] = off[i] + D.nl[i];
    var w = NaN, m = 0;
    for (k = off[i]; k < off[i + 1]; k++) {
      if (D.h[k] !== null && !(D.h[k] <= w)) w = D.h[k];
      if (D.bud[k] === 0) m++;
    }
    if (D.cons[i]) D.cons[i].forEach(function (c) { if (c[5] === 0) m++; });
    worst[i] = w; missed[i] = m;
    low[i] = path(i).toLowerCase();
  }
  function path(a) { return D.dir[a] < 0 ? "" : D.dirs[D.dir[a]] + D.name[a]; }
  function esc(s) {
    return String(s).replace(/[&<>"']/g, function (c) {
      return { "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c];
    });
  }
  var DASH = "\u2013";
  function num(v, d) { return v === null || v === undefined || isNaN(v) ? DASH : v.toFixed(d); }
  function count(v) {
    return v === null || v === undefined ? DASH : String(Math.round(v)).replace(/\B(?=(\d{3})+(?!\d))/g, "\u202f");
  }
  function bytes(v) {
    if (v === null || v === undefined) return DASH;
    if (v < 1024) return v + " B";
    if (v < 1048576) return (v / 1024).toFixed(1) + " KB";
    return (v / 1048576).toFixed(1) + " MB";
  }
  function lastTri(a) { return D.nl[a] ? D.tri[off[a + 1] - 1] : null; }
  function coverage(a) {
    var s = [];
    for (var k = off[a]; k < off[a + 1]; k++) s.push(num(D.sc[k], 3));
    return s.length ? s.join(" \u00b7 ") : DASH;
  }
  function statusText(a) {
    if (D.st[a] === 0 && missed[a]) return "budget missed";
    return STATUS[D.st[a]];
  }
  // Sort keys are numbers (strings by their rank: paths from the data's "pr", classes by name; statuses by
  // severity), so a sort compares doubles only.
  var classRank = D.classes.map(function (c, k) { return k; }).sort(function (x, y) {
    return D.classes[x] < D.classes[y] ? -1 : D.classes[x] > D.classes[y] ? 1 : 0;
  }).reduce(function (r, c, k) { r[c] = k; return r; }, []);
  // Columns: label, sort key (a number; null sorts last), cell HTML.
  var COLS = [
    ["#", function (a) { return a; }, function (a) { return String(a + 1); }, "num"],
    ["asset", function (a) { return D.pr[a]; }, function (a) {
      if (D.dir[a] < 0) return DASH;
      return '<span class="dir">' + esc(D.dirs[D.dir[a]]) + '</span><span class="file">' + esc(D.name[a]) + "</span>";
    }, "path"],
    ["class", function (a) { return D.cls[a] < 0 ? null : classRank[D.cls[a]]; },
      function (a) { return D.cls[a] < 0 ? DASH : esc(D.classes[D.cls[a]]); }, ""],
    ["status", function (a) { return D.st[a] === 1 ? 0 : D.st[a] === 0 ? (missed[a] ? 1 : 2) : D.st[a] + 1; }, function (a) {
      var s = statusText(a);
      return '<span class="' + (s === "ok" ? "st-ok" : s === "failed" || s === "budget missed" ? "st-failed" : "st-skipped") +
        '">' + esc(s) + "</span>";
    }, ""],
    ["LODs", function (a) { return D.nl[a]; }, function (a) { return String(D.nl[a]); }, "num"],
    ["input tris", function (a) { return D.itri[a]; }, function (a) { return count(D.itri[a]); }, "num"],
    ["last LOD tris", lastTri, function (a) { return count(lastTri(a)); }, "num"],
    ["worst Hausdorff %", function (a) { return isNaN(worst[a]) ? null : worst[a]; },
      function (a) { return num(worst[a], 4); }, "num"],
    ["budget", function (a) { return D.nl[a] ? missed[a] : null; }, function (a) {
      if (!D.nl[a]) return DASH;
      var all = D.nl[a] + (D.cons[a] ? D.cons[a].length : 0);
      return missed[a] ? '<span class="st-failed">missed ' + missed[a] + "/" + all + "</span>" : "met";
    }, ""],
    ["screen coverage", function (a) { return D.nl[a] ? D.sc[off[a]] : null; }, coverage, "num"],
    ["input size", function (a) { return D.ib[a]; }, function (a) { return bytes(D.ib[a]); }, "num"],
    ["output size", function (a) { return D.ob[a]; }, function (a) { return bytes(D.ob[a]); }, "num"],
    ["cache hit", function (a) { return D.hit[a]; },
      function (a) { return D.hit[a] === null ? DASH : D.hit[a] ? "yes" : "no"; }, ""]
  ];
  var table = document.getElementById("assets"), body = table.tBodies[0];
  var q = document.getElementById("q"), clsSel = document.getElementById("cls"), stSel = document.getElementById("st");
  var info = document.getElementById("count"), pageInfo = document.getElementById("page");
  var state = { sort: 0, dir: 1, page: 0, open: {} }, sorted = null, view = null;
  D.classes.forEach(function (c, k) {
    var o = document.createElement("option"); o.value = String(k); o.textContent = c; clsSel.appendChild(o);
  });
  var head = table.tHead.rows[0];
  head.innerHTML = "<th></th>" + COLS.map(function (c) {
    return '<th scope="col" tabindex="0" title="Sort by this column">' + esc(c[0]) + "</th>";
  }).join("");
  function sortBy(col) {
    state.dir = state.sort === col ? -state.dir : 1;
    state.sort = col; state.page = 0; sorted = null; update();
  }
  Array.prototype.forEach.call(head.cells, function (th, c) {
    if (c === 0) return;
    th.addEventListener("click", function () { sortBy(c - 1); });
    th.addEventListener("keydown", function (e) {
      if (e.key === "Enter" || e.key === " ") { e.preventDefault(); sortBy(c - 1); }
    });
  });
  function order() {
    if (sorted) return sorted;
    var idx = new Int32Array(n);
    for (var a = 0; a < n; a++) idx[a] = a;
    if (state.sort !== 0 || state.dir !== 1) {
      var key = COLS[state.sort][1], keys = new Float64Array(n), dir = state.dir, v;
      for (a = 0; a < n; a++) { v = key(a); keys[a] = v === null || v === undefined ? NaN : v; }
      idx.sort(function (x, y) {
        var p = keys[x], r = keys[y];
        if (p !== p) return r !== r ? x - y : 1;  // NaN: absent, last in both directions
        if (r !== r) return -1;
        return p === r ? x - y : p < r ? -dir : dir;
      });
    }
    sorted = idx;
    return idx;
  }
  function keep(a, text, cls, st) {
    if (cls !== "" && String(D.cls[a]) !== cls) return false;
    if (st === "failed" && D.st[a] !== 1) return false;
    if (st === "missed" && !(D.st[a] === 0 && missed[a])) return false;
    if (st === "ok" && !(D.st[a] === 0 && !missed[a])) return false;
    if (st === "other" && D.st[a] < 2) return false;
    return text === "" || low[a].indexOf(text) >= 0;
  }
  function filter() {
    var idx = order(), text = q.value.trim().toLowerCase(), cls = clsSel.value, st = stSel.value;
    var out = new Int32Array(n), m = 0;
    for (var j = 0; j < n; j++) if (keep(idx[j], text, cls, st)) out[m++] = idx[j];
    view = out.subarray(0, m);
  }
  var AX = D.axes, W = 280, H = 150, L = 44, R = 24, T = 8, B = 28;
  function decades(r, fallback) {
    var lo = r[0] === null ? fallback[0] : Math.floor(Math.log10(r[0]) + 1e-9);
    var hi = r[1] === null ? fallback[1] : Math.ceil(Math.log10(r[1]) - 1e-9);
    if (hi <= lo) hi = lo + 1;
    return [lo, hi];
  }
  var XD = decades(AX.tri, [0, 6]), YD = decades(AX.err, [-4, 0]);
  function sx(v) { return L + (Math.log10(v) - XD[0]) / (XD[1] - XD[0]) * (W - L - R); }
  var ZERO = H - B - 6, YTOP = T, YBOT = H - B - 18;  // errors of zero: a row of their own below the decades
  function sy(v) { return v > 0 ? YBOT - (Math.log10(v) - YD[0]) / (YD[1] - YD[0]) * (YBOT - YTOP) : ZERO; }
  function label(e) { return e >= 0 && e <= 6 ? String(Math.pow(10, e)) : e < 0 && e >= -6 ? Math.pow(10, e).toFixed(-e) : "1e" + e; }
  function plot(a) {
    var s = '<svg class="chain" viewBox="0 0 ' + W + " " + H + '" width="' + W + '" height="' + H +
      '" role="img" aria-label="error against triangles"><title>Hausdorff (solid) and mean (dashed) error, % of diagonal, against triangles; the source at error 0</title>';
    var step = Math.max(1, Math.ceil((XD[1] - XD[0]) / 6)), e;
    for (e = XD[0]; e <= XD[1]; e += step) {
      s += '<line class="grid" x1="' + sx(Math.pow(10, e)) + '" x2="' + sx(Math.pow(10, e)) + '" y1="' + YTOP + '" y2="' + ZERO + '"/>' +
        '<text x="' + sx(Math.pow(10, e)) + '" y="' + (H - B + 12) + '" text-anchor="middle">' + label(e) + "</text>";
    }
    step = Math.max(1, Math.ceil((YD[1] - YD[0]) / 5));
    for (e = YD[0]; e <= YD[1]; e += step) {
      s += '<line class="grid" x1="' + L + '" x2="' + (W - R) + '" y1="' + sy(Math.pow(10, e)) + '" y2="' + sy(Math.pow(10, e)) + '"/>' +
        '<text x="' + (L - 4) + '" y="' + (sy(Math.pow(10, e)) + 4) + '" text-anchor="end">' + label(e) + "</text>";
    }
    s += '<text x="' + (L - 4) + '" y="' + (ZERO + 4) + '" text-anchor="end">0</text>' +
      '<text x="' + ((L + W - R) / 2) + '" y="' + (H - 4) + '" text-anchor="middle">triangles</text>';
    function chain(field, css) {
      var pts = [];
      if (D.itri[a] > 0) pts.push([sx(D.itri[a]), ZERO]);
      for (var k = off[a]; k < off[a + 1]; k++) {
        if (D.tri[k] > 0 && D[field][k] !== null) pts.push([sx(D.tri[k]), sy(D[field][k])]);
      }
      var p = '<polyline class="' + css + '" points="' + pts.map(function (q) { return q[0].toFixed(1) + "," + q[1].toFixed(1); }).join(" ") + '"/>';
      pts.forEach(function (q) { p += '<circle class="' + css + '" cx="' + q[0].toFixed(1) + '" cy="' + q[1].toFixed(1) + '" r="2.5"/>'; });
      return p;
    }
    return s + chain("mean", "mean") + chain("h", "haus") + "</svg>";
  }
  function detail(a) {
    if (D.err[a] !== undefined) return '<p class="err">' + esc(D.err[a]) + "</p>";
    if (!D.nl[a]) return '<p class="empty">No LODs.</p>';
    var s = '<table class="lods"><thead><tr><th>LOD</th><th>target</th><th>target tris</th><th>triangles</th>' +
      "<th>error bound %</th><th>mean %</th><th>Hausdorff %</th><th>screen coverage</th><th>stop reason</th>" +
      "<th>budget</th></tr></thead><tbody>";
    for (var k = off[a]; k < off[a + 1]; k++) {
      var bud = D.bud[k] === null ? DASH : D.bud[k] ? "met" : '<span class="st-failed">missed</span>';
      if (D.why[k] >= 0) bud += ": " + esc(D.reasons[D.why[k]]);
      s += "<tr><td>" + num(D.lv[k], 0) + "</td><td>" + (D.tgt[k] < 0 ? DASH : esc(D.targets[D.tgt[k]])) +
        '</td><td class="num">' + count(D.ttri[k]) + '</td><td class="num">' + count(D.tri[k]) +
        '</td><td class="num">' + num(D.eb[k], 4) + '</td><td class="num">' + num(D.mean[k], 4) +
        '</td><td class="num">' + num(D.h[k], 4) + '</td><td class="num">' + num(D.sc[k], 4) +
        "</td><td>" + (D.stop[k] < 0 ? DASH : esc(D.stops[D.stop[k]])) + "</td><td>" + bud + "</td></tr>";
    }
    return '<div class="detail">' + plot(a) + s + "</tbody></table></div>" + separate(a) +
      (D.pic[a] ? '<div class="pics" data-pics="' + a + '"></div>' : "");
  }
  // Collision and occluder LODs: separate outputs, no render level, so a table of their own.
  function separate(a) {
    if (!D.cons[a]) return "";
    var s = '<table class="separate"><thead><tr><th>separate LOD</th><th>target</th><th>triangles</th>' +
      "<th>Hausdorff %</th><th>volume change %</th><th>budget</th><th>output</th></tr></thead><tbody>";
    D.cons[a].forEach(function (c) {
      var bud = c[5] === null ? DASH : c[5] ? "met" : '<span class="st-failed">missed</span>';
      if (c[6] !== null) bud += ": " + esc(c[6]);
      s += "<tr><td>" + esc(c[0]) + "</td><td>" + esc(c[1]) + '</td><td class="num">' + count(c[2]) +
        '</td><td class="num">' + num(c[3], 4) + '</td><td class="num">' + num(c[4], 2) + "</td><td>" + bud +
        "</td><td>" + esc(c[7]) + "</td></tr>";
    });
    return s + "</tbody></table>";
  }
  // The LOD pictures beside the report (report_files/<asset path>/lodK.png), made as elements rather than markup
  // so that every URL goes through encodeURIComponent; loaded lazily, when the row is open and in view.
  function pictures() {
    Array.prototype.forEach.call(body.querySelectorAll("div.pics"), function (box) {
      var a = Number(box.getAttribute("data-pics")), base = D.picdir + path(a).split("/").map(encodeURIComponent).join("/");
      for (var k = 0; k < D.pic[a]; k++) {
        var fig = document.createElement("figure"), img = document.createElement("img"), cap = document.createElement("figcaption");
        img.loading = "lazy";
        img.width = img.height = 160;
        img.alt = k ? "LOD " + k : "source";
        img.src = base + "/lod" + k + ".png";
        var tris = k ? D.tri[off[a] + k - 1] : D.itri[a];
        cap.textContent = (k ? "LOD " + k : "source") + " \u00b7 " + count(tris) + " tris";
        fig.appendChild(img); fig.appendChild(cap); box.appendChild(fig);
      }
    });
  }
  function render() {
    var pages = Math.max(1, Math.ceil(view.length / PAGE));
    if (state.page >= pages) state.page = pages - 1;
    var html = [], end = Math.min(view.length, (state.page + 1) * PAGE);
    for (var j = state.page * PAGE; j < end; j++) {
      var a = view[j], open = state.open[a] === true;
      html.push('<tr data-asset="' + a + '" class="' + (D.st[a] === 1 ? "failed" : missed[a] ? "missed" : "") +
        '"><td><button class="toggle" aria-expanded="' + open + '" title="LODs">' + (open ? "\u25be" : "\u25b8") + "</button></td>");
      for (var c = 0; c < COLS.length; c++) {
        html.push('<td class="' + COLS[c][3] + '"' + (c === 1 ? ' title="' + esc(path(a)) + '"' : "") + ">" + COLS[c][2](a) + "</td>");
      }
      html.push("</tr>");
      if (open) html.push('<tr class="expanded"><td></td><td colspan="' + COLS.length + '">' + detail(a) + "</td></tr>");
    }
    body.innerHTML = html.join("");
    pictures();
    info.textContent = view.length + " of " + n + " assets";
    pageInfo.textContent = "page " + (state.page + 1) + " of " + pages;
    Array.prototype.forEach.call(head.cells, function (th, c) {
      if (c === 0) return;
      if (c - 1 === state.sort) th.setAttribute("aria-sort", state.dir > 0 ? "ascending" : "descending");
      else th.removeAttribute("aria-sort");
    });
  }
  // Per class: every LOD of every asset, Hausdorff error against triangles, on the axes of the asset plots (one
  // scale for all classes); a canvas, drawn when the section is first opened, since 100 000 assets are 300 000
  // points. Errors of zero sit on their own row below the lowest decade.
  var LEVEL_COLOURS = ["#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2"];
  function overview() {
    var box = document.getElementById("overview-plots"), C = D.classes.length, by = [], a, k, c;
    for (c = 0; c <= C; c++) by.push([]);
    for (a = 0; a < n; a++) {
      c = D.cls[a] < 0 ? C : D.cls[a];
      for (k = off[a]; k < off[a + 1]; k++) if (D.tri[k] > 0 && D.h[k] !== null) by[c].push(k);
    }
    var OW = 2 * W, OH = 2 * H, ratio = window.devicePixelRatio || 1;
    function ox(v) { return 2 * sx(v); }
    function oy(v) { return 2 * sy(v); }
    for (c = 0; c <= C; c++) {
      if (!by[c].length) continue;
      var fig = document.createElement("figure"), cap = document.createElement("figcaption"), cv = document.createElement("canvas");
      cap.textContent = (c < C ? D.classes[c] : "(no class)") + " \u00b7 " + by[c].length + " LODs";
      cv.className = "overview";
      cv.width = OW * ratio; cv.height = OH * ratio; cv.style.width = OW + "px"; cv.style.height = OH + "px";
      cv.setAttribute("data-points", String(by[c].length));
      cv.setAttribute("role", "img");
      cv.setAttribute("aria-label", "Hausdorff error against triangles of every LOD of class " + cap.textContent);
      var g = cv.getContext("2d"), e;
      g.scale(ratio, ratio);
      g.font = "11px system-ui, sans-serif"; g.fillStyle = "#1d1f23"; g.strokeStyle = "#e6e9ee";
      g.textAlign = "center";
      var step = Math.max(1, Math.ceil((XD[1] - XD[0]) / 6));
      for (e = XD[0]; e <= XD[1]; e += step) {
        g.beginPath(); g.moveTo(ox(Math.pow(10, e)), 2 * YTOP); g.lineTo(ox(Math.pow(10, e)), 2 * ZERO); g.stroke();
        g.fillText(label(e), ox(Math.pow(10, e)), OH - 2 * B + 24);
      }
      g.fillText("triangles", OW / 2, OH - 8);
      g.textAlign = "right";
      step = Math.max(1, Math.ceil((YD[1] - YD[0]) / 5));
      for (e = YD[0]; e <= YD[1]; e += step) {
        g.beginPath(); g.moveTo(2 * L, oy(Math.pow(10, e))); g.lineTo(OW - 2 * R, oy(Math.pow(10, e))); g.stroke();
        g.fillText(label(e), 2 * L - 6, oy(Math.pow(10, e)) + 4);
      }
      g.fillText("0", 2 * L - 6, 2 * ZERO + 4);
      g.save(); g.translate(12, OH / 2); g.rotate(-Math.PI / 2); g.textAlign = "center";
      g.fillText("Hausdorff % of diagonal", 0, 0); g.restore();
      by[c].forEach(function (k) {
        g.fillStyle = LEVEL_COLOURS[Math.min(Math.max((D.lv[k] || 1) - 1, 0), LEVEL_COLOURS.length - 1)];
        g.fillRect(ox(D.tri[k]) - 2, oy(D.h[k]) - 2, 4, 4);
      });
      fig.appendChild(cap); fig.appendChild(cv); box.appendChild(fig);
    }
    var legend = document.getElementById("overview-legend");
    if (legend) legend.innerHTML = LEVEL_COLOURS.map(function (col, i) {
      return '<span class="key"><b style="color:' + col + '">\u25a0</b> LOD ' + (i + 1) +
        (i === LEVEL_COLOURS.length - 1 ? "+" : "") + "</span>";
    }).join("");
  }
  var ov = document.getElementById("overview");
  if (ov) ov.addEventListener("toggle", function () {
    if (ov.open && !ov.hasAttribute("data-drawn")) { ov.setAttribute("data-drawn", ""); overview(); }
  });
  function update() { filter(); render(); }
  body.addEventListener("click", function (e) {
    var b = e.target.closest("button.toggle");
    if (!b) return;
    var a = Number(b.closest("tr").getAttribute("data-asset"));
    state.open[a] = !state.open[a];
    render();
  });
  q.addEventListener("input", function () { state.page = 0; update(); });
  clsSel.addEventListener("change", function () { state.page = 0; update(); });
  stSel.addEventListener("change", function () { state.page = 0; update(); });
  document.getElementById("prev").addEventListener("click", function () { if (state.page > 0) { state.page--; render(); } });
  document.getElementById("next").addEventListener("click", function () { state.page++; render(); });
  update();
})();
)js";

void text_cell(std::string& out, const std::optional<std::string>& v, std::string_view css_class = {}) {
  if (!v) {
    out += "<td class=\"na\">";
    out += kDash;
    out += "</td>";
    return;
  }
  out += "<td";
  if (!css_class.empty()) {
    out += " class=\"";
    out += css_class;
    out += '"';
  }
  out += '>';
  append_escaped(out, *v);
  out += "</td>";
}

void header_cell(std::string& out, std::string_view label, bool numeric, bool sorted_ascending = false) {
  out += "<th scope=\"col\" data-type=\"";
  out += numeric ? "num" : "text";
  out += '"';
  if (sorted_ascending) out += " aria-sort=\"ascending\"";
  out += '>';
  out += label;  // labels are literals of this file
  out += "</th>";
}


// ----- Header

void figure(std::string& out, std::string_view label, const std::string& value_html, bool bad = false) {
  out += bad ? "<div class=\"figure bad\">" : "<div class=\"figure\">";
  out += "<div class=\"v\">";
  out += value_html;
  out += "</div><div class=\"k\">";
  out += label;
  out += "</div></div>\n";
}

std::string count_or_dash(const std::optional<double>& v) {
  return v ? count(*v) : std::string(kDash);
}
std::string escaped_or_dash(const std::optional<std::string>& v) {
  return v ? escaped(*v) : std::string(kDash);
}

void render_header(std::string& out, const json& report) {
  out += "<header>\n<h1>lodforge batch report</h1>\n<p class=\"meta\">";
  const auto meta = [&](std::string_view label, const std::string& value_html) {
    out += "<span>";
    out += label;
    out += " <b>";
    out += value_html;
    out += "</b></span>";
  };
  meta("lodforge", escaped_or_dash(text(report, "lodforge_version")));
  meta("config", escaped_or_dash(text(report, "config_file")));
  meta("input", escaped_or_dash(text(report, "input_dir")));
  meta("output", escaped_or_dash(text(report, "output_dir")));
  meta("jobs", count_or_dash(number(report, "jobs")));
  meta("shard", escaped_or_dash(text(report, "shard")));
  out += "</p>\n";

  const json& s = member(report, "summary");
  const std::optional<double> failed = number(s, "failed");
  const std::optional<double> in = number(s, "input_triangles");
  const std::optional<double> kept = number(s, "output_triangles");
  out += "<div class=\"figures\">\n";
  figure(out, "assets", count_or_dash(number(s, "assets")));
  figure(out, "succeeded", count_or_dash(number(s, "succeeded")));
  figure(out, "failed", count_or_dash(failed), failed && *failed > 0);
  figure(out, "skipped", count_or_dash(number(s, "skipped")));
  if (const std::optional<double> n = number(s, "not_started"); n && *n > 0) figure(out, "not started", count_or_dash(n));
  figure(out, "cache hits", count_or_dash(number(s, "cache_hits")));
  figure(out, "LODs", count_or_dash(number(s, "lods")));
  const std::optional<double> missed = number(s, "lods_missed");
  figure(out, "LODs missed budget", count_or_dash(missed), missed && *missed > 0);
  if (const std::optional<double> n = number(s, "conservative_lods")) {  // only runs that built any
    const std::optional<double> n_missed = number(s, "conservative_lods_missed");
    figure(out, "collision/occluder LODs", count_or_dash(n));
    figure(out, "of those missed budget", count_or_dash(n_missed), n_missed && *n_missed > 0);
  }
  figure(out, "input triangles", count_or_dash(in));
  figure(out, "output triangles", count_or_dash(kept));
  figure(out, "output / input", in && kept && *in > 0 ? fixed(*kept / *in, 4) : std::string(kDash));
  const std::optional<double> seconds = number(s, "seconds");
  figure(out, "seconds", seconds ? fixed(*seconds, 2) : std::string(kDash));
  out += "</div>\n</header>\n";
}

// ----- Failures and skipped assets

void render_problem_table(std::string& out, const std::vector<const Asset*>& assets, std::string_view error_label) {
  out += "<div class=\"scroll\"><table class=\"sortable\"><thead><tr>";
  header_cell(out, "asset", false);
  header_cell(out, "class", false);
  header_cell(out, error_label, false);
  out += "</tr></thead><tbody>\n";
  for (std::size_t i = 0; i < assets.size() && i < kProblemRows; ++i) {
    out += "<tr data-rank=\"" + std::to_string(i) + "\">";
    text_cell(out, assets[i]->path, "path");
    text_cell(out, assets[i]->class_name);
    text_cell(out, assets[i]->error, "err");
    out += "</tr>\n";
  }
  out += "</tbody></table></div>\n";
  if (assets.size() > kProblemRows) {
    out += "<p class=\"meta\">and " + std::to_string(assets.size() - kProblemRows) +
           " more: the assets table below filters by status.</p>\n";
  }
}

void render_failures(std::string& out, const std::vector<Asset>& assets) {
  std::vector<const Asset*> failed, skipped, not_started;
  for (const Asset& a : assets) {
    if (a.failed()) failed.push_back(&a);
    if (a.status == "skipped") skipped.push_back(&a);
    if (a.status == "not_started") not_started.push_back(&a);
  }
  const auto by_path = [](const Asset* x, const Asset* y) { return x->path_or_empty() < y->path_or_empty(); };
  std::stable_sort(failed.begin(), failed.end(), by_path);
  std::stable_sort(skipped.begin(), skipped.end(), by_path);

  out += "<section id=\"failures\">\n<h2>Failures (" + std::to_string(failed.size()) + ")</h2>\n";
  if (failed.empty()) {
    out += "<p class=\"empty\">No asset failed.</p>\n";
  } else {
    render_problem_table(out, failed, "error");
  }
  if (!skipped.empty()) {  // folded: skips are expected (assets no class matches), failures are not
    out += "<details><summary>Skipped (" + std::to_string(skipped.size()) + ")</summary>\n";
    render_problem_table(out, skipped, "reason");
    out += "</details>\n";
  }
  if (!not_started.empty()) {  // the run was stopped; a re-run resumes them
    out += "<details><summary>Not started (" + std::to_string(not_started.size()) + ")</summary>\n";
    render_problem_table(out, not_started, "reason");
    out += "</details>\n";
  }
  out += "</section>\n";
}

// ----- Changes since the previous run into the same output

constexpr std::size_t kChangeLines = 100;  // per kind; report.json and `lodforge diff-reports` list them all

void render_changes(std::string& out, const json& report) {
  const json& changes = member(report, "changes");
  if (!changes.is_object()) return;
  const auto list = [&](const char* key) -> const json& { return member(changes, key); };
  const auto size = [&](const char* key) { return list(key).is_array() ? list(key).size() : std::size_t{0}; };
  out += "<section id=\"changes\">\n<h2>Changes since the previous run</h2>\n<p class=\"meta\">";
  out += "previous run <b>" + count_or_dash(number(changes, "previous_assets")) + "</b> assets; ";
  out += "<b>" + std::to_string(size("added")) + "</b> added, <b>" + std::to_string(size("removed")) +
         "</b> removed, <b>" + std::to_string(size("rebuilt")) + "</b> rebuilt, <b>" +
         std::to_string(size("status_changed")) + "</b> changed status, <b>" + std::to_string(size("lods_moved")) +
         "</b> LODs moved by more than 5% (triangles or Hausdorff distance)</p>\n";
  const auto section = [&](const char* key, const char* title, auto line) {
    const json& l = list(key);
    if (!l.is_array() || l.empty()) return;
    out += "<details><summary>" + std::string(title) + " (" + std::to_string(l.size()) + ")</summary><ul>\n";
    std::size_t shown = 0;
    for (const json& e : l) {
      if (shown++ == kChangeLines) {
        out += "<li class=\"muted\">and " + std::to_string(l.size() - kChangeLines) + " more (report.json)</li>\n";
        break;
      }
      out += "<li>";
      line(e);
      out += "</li>\n";
    }
    out += "</ul></details>\n";
  };
  const auto path = [&](const json& e) { append_escaped(out, e.is_string() ? e.get<std::string>() : std::string(kDash)); };
  section("added", "Added", path);
  section("removed", "Removed", path);
  section("rebuilt", "Rebuilt", path);
  section("status_changed", "Status changed", [&](const json& e) {
    append_escaped(out, text(e, "path").value_or(std::string(kDash)));
    out += ": ";
    append_escaped(out, text(e, "from").value_or(std::string(kDash)));
    out += " \xE2\x86\x92 ";
    append_escaped(out, text(e, "to").value_or(std::string(kDash)));
  });
  section("lods_moved", "LODs moved", [&](const json& e) {
    append_escaped(out, text(e, "path").value_or(std::string(kDash)));
    const auto pair = [&](const char* key, int decimals, double scale, const char* label) {
      const json& p = member(e, key);
      if (!p.is_array() || p.size() != 2) return;
      const auto v = [&](const json& x) {
        return x.is_number() ? fixed(x.get<double>() * scale, decimals) : std::string(kDash);
      };
      out += std::string(" ") + label + " " + v(p[0]) + " \xE2\x86\x92 " + v(p[1]);
    };
    if (const std::optional<std::int64_t> level = integer(e, "level")) out += " LOD" + std::to_string(*level) + ":";
    if (member(e, "lod_count").is_array()) {
      pair("lod_count", 0, 1, "LODs");
    } else {
      pair("triangles", 0, 1, "triangles");
      pair("hausdorff_rel", 4, 100, "Hausdorff %");
    }
  });
  out += "</section>\n";
}

// ----- The assets table (filled by the script)

void render_assets(std::string& out, const std::vector<Asset>& assets, const std::vector<const Asset*>& order) {
  out += "<section id=\"assets-section\">\n<h2>Assets, worst first</h2>\n";
  out +=
      "<p class=\"meta\">One row per asset: failed first, then assets with a LOD that missed its budget, then by the "
      "largest measured Hausdorff distance over their LODs (% of the source's bounding-box diagonal). Click a "
      "column header to sort, \xE2\x96\xB8 to show an asset's LODs and its error against triangles.</p>\n";
  out += "<div class=\"controls\"><input id=\"q\" type=\"search\" placeholder=\"search paths\" aria-label=\"search "
         "paths\"> <select id=\"cls\" aria-label=\"class\"><option value=\"\">all classes</option>"
         "<option value=\"-1\">(no class)</option></select> <select id=\"st\" aria-label=\"status\">"
         "<option value=\"\">all statuses</option><option value=\"failed\">failed</option>"
         "<option value=\"missed\">budget missed</option><option value=\"ok\">ok (budgets met)</option>"
         "<option value=\"other\">skipped or not started</option></select> <span id=\"count\"></span> "
         "<button id=\"prev\">\xE2\x97\x80</button> <span id=\"page\"></span> <button id=\"next\">\xE2\x96\xB6</button>"
         "</div>\n";
  out += "<noscript><p class=\"empty\">The table needs JavaScript; report.json holds the same data.</p></noscript>\n";
  out += "<div class=\"scroll\"><table id=\"assets\"><thead><tr></tr></thead><tbody></tbody></table></div>\n";
  (void)assets;
  render_data(out, order);
  out += "</section>\n";
}

// ----- Worst assets

// ----- Plots

// One axis: a data range, its ticks, and the mapping to pixels.
struct Axis {
  bool log = false;
  double lo = 0, hi = 1;            // data units; positive when log
  std::vector<double> ticks;        // labelled
  std::vector<double> minor_ticks;  // gridlines only (2..9 x 10^k on short log axes)
  int decimals = 0;                 // tick label precision of a linear axis

  double to_pixel(double v, double px_lo, double px_hi) const {
    const double t = log ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)) : (v - lo) / (hi - lo);
    return px_lo + t * (px_hi - px_lo);
  }
};

// Linear from 0 to a "nice" bound above max (steps of 1, 2 or 5 x 10^k, about five of them).
Axis linear_axis_from_zero(double max) {
  Axis a;
  if (!(max > 0)) max = 1;
  const double raw_step = max / 5;
  const int exponent = static_cast<int>(std::floor(std::log10(raw_step)));
  const double magnitude = std::pow(10.0, exponent);
  const double n = raw_step / magnitude;
  const double step = (n <= 1 ? 1 : n <= 2 ? 2 : n <= 5 ? 5 : 10) * magnitude;
  const int steps = std::max(1, static_cast<int>(std::ceil(max / step - 1e-9)));
  a.lo = 0;
  a.hi = steps * step;
  for (int k = 0; k <= steps; ++k) a.ticks.push_back(k * step);
  a.decimals = std::max(0, -exponent + (n > 5 ? -1 : 0));
  return a;
}

// "0.001", "1", "100"; far-off decades as "1e-9".
std::string decade_label(double v) {
  const int e = static_cast<int>(std::lround(std::log10(v)));
  if (e >= 0 && e <= 6) return fixed(v, 0);
  if (e < 0 && e >= -6) return fixed(v, -e);
  return "1e" + std::to_string(e);
}

std::string tick_label(const Axis& axis, double v) {
  return axis.log ? decade_label(v) : fixed(v, axis.decimals);
}

std::string px(double v) {
  return fixed(v, 1);
}

bool plottable(double v) {
  return v >= 1e-280 && v <= 1e280;
}


void axis_lines(std::string& out, const Axis& axis, bool horizontal, double x0, double y0, double x1, double y1) {
  const auto line = [&](double v, std::string_view css) {
    if (horizontal) {
      const double x = axis.to_pixel(v, x0, x1);
      out += "<line class=\"" + std::string(css) + "\" x1=\"" + px(x) + "\" y1=\"" + px(y0) + "\" x2=\"" + px(x) +
             "\" y2=\"" + px(y1) + "\"/>";
    } else {
      const double y = axis.to_pixel(v, y1, y0);  // y grows downwards
      out += "<line class=\"" + std::string(css) + "\" x1=\"" + px(x0) + "\" y1=\"" + px(y) + "\" x2=\"" + px(x1) +
             "\" y2=\"" + px(y) + "\"/>";
    }
  };
  for (const double v : axis.minor_ticks) line(v, "minor");
  for (const double v : axis.ticks) line(v, "grid");
  for (const double v : axis.ticks) {
    if (horizontal) {
      out += "<text x=\"" + px(axis.to_pixel(v, x0, x1)) + "\" y=\"" + px(y1 + 15) + "\" text-anchor=\"middle\">" +
             tick_label(axis, v) + "</text>";
    } else {
      out += "<text x=\"" + px(x0 - 6) + "\" y=\"" + px(axis.to_pixel(v, y1, y0) + 4) + "\" text-anchor=\"end\">" +
             tick_label(axis, v) + "</text>";
    }
  }
  out += '\n';
}

void svg_open(std::string& out, double width, double height, const std::string& label_html) {
  out += "<svg viewBox=\"0 0 " + px(width) + ' ' + px(height) + "\" width=\"" + px(width) + "\" height=\"" +
         px(height) + "\" role=\"img\" aria-label=\"" + label_html + "\"><title>" + label_html + "</title>\n";
}

// One class: measured mean error against achieved ratio, a dot per LOD. Returns nothing; LODs that a log axis

// The ten assets with the largest Hausdorff distance over their LODs.
void render_worst_assets(std::string& out, const std::vector<Asset>& assets) {
  std::vector<const Asset*> worst;
  for (const Asset& a : assets) {
    if (a.max_hausdorff_rel && (*a.max_hausdorff_rel == 0 || plottable(*a.max_hausdorff_rel))) worst.push_back(&a);
  }
  std::stable_sort(worst.begin(), worst.end(), [](const Asset* a, const Asset* b) {
    if (*a->max_hausdorff_rel != *b->max_hausdorff_rel) return *a->max_hausdorff_rel > *b->max_hausdorff_rel;
    return a->path_or_empty() < b->path_or_empty();
  });
  if (worst.size() > kWorstAssets) worst.resize(kWorstAssets);

  constexpr double kWidth = 720, kLabelWidth = 280, kBarRight = 640, kRowHeight = 22, kHeaderTop = 10;
  const double axis_y = kHeaderTop + std::max<double>(1, static_cast<double>(worst.size())) * kRowHeight + 4;
  const double height = axis_y + 40;
  out += "<figure>\n<figcaption>Worst assets <small>largest Hausdorff distance over all LODs, top " +
         std::to_string(kWorstAssets) + "</small></figcaption>\n";
  svg_open(out, kWidth, height, "worst assets by Hausdorff distance");
  if (worst.empty()) {
    out += "<text class=\"muted\" x=\"" + px(kWidth / 2) + "\" y=\"" + px(kHeaderTop + 14) +
           "\" text-anchor=\"middle\">no asset has a measured Hausdorff distance</text>\n</svg>\n</figure>\n";
    return;
  }
  const Axis axis = linear_axis_from_zero(*worst.front()->max_hausdorff_rel * 100.0);
  axis_lines(out, axis, true, kLabelWidth, kHeaderTop, kBarRight, axis_y);
  out += "<text x=\"" + px((kLabelWidth + kBarRight) / 2) + "\" y=\"" + px(height - 6) +
         "\" text-anchor=\"middle\">Hausdorff distance, % of diagonal</text>\n";
  for (std::size_t i = 0; i < worst.size(); ++i) {
    const Asset& a = *worst[i];
    const double value = *a.max_hausdorff_rel * 100.0;
    const double top = kHeaderTop + static_cast<double>(i) * kRowHeight;
    const double bar_end = axis.to_pixel(value, kLabelWidth, kBarRight);
    out += "<g><title>";
    append_escaped(out, a.path_or_empty());
    if (a.class_name) {
      out += " (";
      append_escaped(out, *a.class_name);
      out += ')';
    }
    out += ": " + fixed(value, 4) + "%</title>";
    out += "<text x=\"" + px(kLabelWidth - 8) + "\" y=\"" + px(top + 15) + "\" text-anchor=\"end\">";
    append_escaped(out, tail_ellipsized(a.path_or_empty(), kBarLabelCodePoints));
    out += "</text><rect x=\"" + px(kLabelWidth) + "\" y=\"" + px(top + 4) + "\" width=\"" +
           px(std::max(0.0, bar_end - kLabelWidth)) + "\" height=\"" + px(kRowHeight - 8) +
           "\" fill=\"#e15759\"/><text x=\"" + px(bar_end + 4) + "\" y=\"" + px(top + 15) + "\">" + fixed(value, 3) +
           "</text></g>\n";
  }
  out += "</svg>\n</figure>\n";
}

void render_effective_config(std::string& out, const json& report) {
  const json* config = field(report, "effective_config");
  if (config == nullptr) return;
  out += "<section id=\"config\">\n<details><summary>Effective config</summary>\n<pre>";
  // nlohmann::json objects iterate in key order, so the dump is deterministic; `replace` keeps invalid UTF-8 in
  // a string from throwing, and NaN dumps as null.
  append_escaped(out, config->dump(2, ' ', false, json::error_handler_t::replace));
  out += "</pre>\n</details>\n</section>\n";
}



}  // namespace

std::string render_report_html(const nlohmann::json& report) {
  const std::vector<Asset> assets = read_assets(report);
  const std::vector<const Asset*> order = order_assets(assets);

  std::string out;
  out.reserve(32768 + assets.size() * 400);
  out += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  // Self-contained by construction, and enforced: the browser refuses any load the page did not inline.
  out +=
      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'; "
      "script-src 'unsafe-inline'; img-src data: 'self' file:\">\n";
  out += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>lodforge report";
  if (const std::optional<std::string> config_file = text(report, "config_file")) {
    out += " \xE2\x80\x94 ";
    append_escaped(out, *config_file);
  }
  out += "</title>\n<style>";
  out += kStyle;
  out += "</style>\n</head>\n<body>\n";

  render_header(out, report);
  render_changes(out, report);
  if (assets.empty()) {
    out += "<p class=\"empty\" id=\"no-assets\">This report has no assets.</p>\n";
  } else {
    render_failures(out, assets);
    render_assets(out, assets, order);
    out += "<section id=\"overview-section\">\n<h2>Error against triangles by class</h2>\n<details id=\"overview\">"
           "<summary>Every LOD of every asset, one plot per class, on the axes of the asset plots</summary>\n"
           "<p class=\"meta\" id=\"overview-legend\"></p><div class=\"plots\" id=\"overview-plots\"></div>\n"
           "</details>\n</section>\n";
    out += "<section id=\"plots\">\n<h2>Worst assets</h2>\n<div class=\"plots\">\n";
    render_worst_assets(out, assets);
    out += "</div>\n</section>\n";
    out += "<script>";
    out += kScript;
    out += "</script>\n";
  }
  render_effective_config(out, report);
  out += "</body>\n</html>\n";
  return out;
}

}  // namespace lodforge::batch
