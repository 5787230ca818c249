// report.html: the batch report as one self-contained page (issue 5, "Report").
//
// No papers here: this file is presentation. Error goes on a log axis because a LOD chain spans decades of error;
// the kept fraction of triangles goes on x, log too when a class's ratios span a decade. The driver is a pipeline
// of small passes:
//   read_assets      the document's "assets" array -> a typed model; anything missing or malformed is "absent"
//   order_rows       one row per asset x LOD, worst first
//   render_*         one function per page section, each appending to the page
// SVG is written by hand rather than by a plotting library: two chart kinds, deterministic bytes, no
// dependency, and nothing the page would have to fetch.
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

namespace lodforge::batch {
namespace {

using nlohmann::json;

constexpr std::string_view kDash = "\xE2\x80\x93";         // "–" (U+2013): what absent values show
constexpr std::string_view kReplacement = "\xEF\xBF\xBD";  // U+FFFD: stands in for bytes HTML can't carry
constexpr std::string_view kEllipsis = "\xE2\x80\xA6";     // "…"
constexpr std::string_view kNarrowSpace = "\xE2\x80\xAF";  // digit grouping in counts: "1 234 567"
constexpr std::size_t kWorstAssets = 10;                   // bars in the worst-assets chart
constexpr std::size_t kBarLabelCodePoints = 40;            // longer paths keep their tail (the file name)

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

// Shortest round-trip form: sort keys in data-v attributes, which the page's script parses back.
std::string shortest(double v) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), r.ptr);
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

std::string percent(double fraction) {
  return fixed(fraction * 100.0, 4);
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
  std::optional<std::string> budget;  // "met", or "missed: " and the reasons
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
  std::optional<double> max_hausdorff_rel;  // over the LODs: the asset's worst measured error

  bool failed() const { return status == "failed"; }
  std::string_view path_or_empty() const { return path ? std::string_view(*path) : std::string_view(); }
};

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
  const json& budget = member(j, "budget");
  if (const std::optional<std::string> status = text(budget, "status")) {
    std::string b = *status;
    const json& reasons = member(budget, "reasons");
    if (reasons.is_array()) {
      for (const json& r : reasons) {
        if (r.is_string()) b += (b == *status ? ": " : "; ") + r.get<std::string>();
      }
    }
    lod.budget = std::move(b);
  }
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
// The table's rows, worst first.

struct Row {
  const Asset* asset = nullptr;
  const Lod* lod = nullptr;  // nullptr: an asset without LODs (failed, skipped), shown as one row of its own
};

// Failed assets on top (they have no error to compare), then LODs that missed their budget, then larger
// Hausdorff first, rows without a measurement last; ties by path, then document order (stable sort).
std::vector<Row> order_rows(const std::vector<Asset>& assets) {
  std::vector<Row> rows;
  for (const Asset& a : assets) {
    if (a.lods.empty()) rows.push_back({&a, nullptr});
    for (const Lod& l : a.lods) rows.push_back({&a, &l});
  }
  const auto hausdorff = [](const Row& r) { return r.lod ? r.lod->hausdorff_rel : std::nullopt; };
  std::stable_sort(rows.begin(), rows.end(), [&](const Row& x, const Row& y) {
    if (x.asset->failed() != y.asset->failed()) return x.asset->failed();
    const bool mx = x.lod && x.lod->missed(), my = y.lod && y.lod->missed();
    if (mx != my) return mx;
    const std::optional<double> hx = hausdorff(x), hy = hausdorff(y);
    if (hx.has_value() != hy.has_value()) return hx.has_value();
    if (hx && *hx != *hy) return *hx > *hy;
    return x.asset->path_or_empty() < y.asset->path_or_empty();
  });
  return rows;
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
td.path { word-break: break-all; min-width: 14em; }
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
pre { background: var(--head); padding: 8px 12px; overflow-x: auto; font-size: 12px; }
)css";

// Click (or Enter/Space on a focused header) sorts by that column; again reverses. Numeric columns sort on the
// cell's data-v, text columns on its text; absent values ("–", class "na") stay last in both directions, and
// ties fall back to the initial worst-first rank, so every order is deterministic.
constexpr std::string_view kScript = R"js(
(function () {
  "use strict";
  function key(cell, numeric) {
    if (!cell || cell.classList.contains("na")) return null;
    if (!numeric) return cell.textContent;
    var v = parseFloat(cell.getAttribute("data-v"));
    return isNaN(v) ? null : v;
  }
  function sortTable(table, col) {
    var head = table.tHead.rows[0].cells, th = head[col];
    var ascending = th.getAttribute("aria-sort") !== "ascending";
    for (var i = 0; i < head.length; i++) head[i].removeAttribute("aria-sort");
    th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    var numeric = th.getAttribute("data-type") === "num", dir = ascending ? 1 : -1;
    var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = key(a.cells[col], numeric), y = key(b.cells[col], numeric);
      if (x === null && y !== null) return 1;
      if (y === null && x !== null) return -1;
      if (x !== null) {
        var c = numeric ? x - y : x.localeCompare(y, undefined, { numeric: true });
        if (c !== 0) return c < 0 ? -dir : dir;
      }
      return Number(a.getAttribute("data-rank")) - Number(b.getAttribute("data-rank"));
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  Array.prototype.forEach.call(document.querySelectorAll("table.sortable"), function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, col) {
      th.tabIndex = 0;
      th.title = "Sort by this column";
      th.addEventListener("click", function () { sortTable(table, col); });
      th.addEventListener("keydown", function (e) {
        if (e.key === "Enter" || e.key === " ") { e.preventDefault(); sortTable(table, col); }
      });
    });
  });
})();
)js";

// ----- Table cells

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

template <class Format>
void number_cell(std::string& out, const std::optional<double>& v, Format format) {
  if (!v) {
    out += "<td class=\"num na\">";
    out += kDash;
    out += "</td>";
    return;
  }
  out += "<td class=\"num\" data-v=\"";
  out += shortest(*v);
  out += "\">";
  out += format(*v);
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

// Known statuses get a CSS class; anything else is shown as text but never becomes markup.
std::string_view status_class(const std::optional<std::string>& status) {
  if (status == "ok") return "st-ok";
  if (status == "failed") return "st-failed";
  if (status == "skipped" || status == "not_started") return "st-skipped";
  return {};
}

std::optional<std::string> yes_no(const std::optional<bool>& v) {
  if (!v) return std::nullopt;
  return std::string(*v ? "yes" : "no");
}

std::optional<std::string> target_text(const Lod& lod) {
  if (!lod.target_kind && !lod.target_value) return std::nullopt;
  std::string s = lod.target_kind.value_or(std::string(kDash));
  s += ' ';
  s += lod.target_value ? compact(*lod.target_value) : std::string(kDash);
  return s;
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
  for (std::size_t i = 0; i < assets.size(); ++i) {
    out += "<tr data-rank=\"" + std::to_string(i) + "\">";
    text_cell(out, assets[i]->path, "path");
    text_cell(out, assets[i]->class_name);
    text_cell(out, assets[i]->error, "err");
    out += "</tr>\n";
  }
  out += "</tbody></table></div>\n";
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

// ----- The asset x LOD table

void render_lod_table(std::string& out, const std::vector<Row>& rows) {
  out += "<section id=\"lods-section\">\n<h2>Assets and LODs, worst first</h2>\n";
  out +=
      "<p class=\"meta\">Failed assets first, then by measured Hausdorff distance. Errors are % of the source's "
      "bounding-box diagonal. Click a column header to sort.</p>\n";
  out += "<div class=\"scroll\"><table id=\"lods\" class=\"sortable\"><thead><tr>";
  header_cell(out, "#", true, true);
  header_cell(out, "asset", false);
  header_cell(out, "class", false);
  header_cell(out, "status", false);
  header_cell(out, "cache hit", false);
  header_cell(out, "LOD", true);
  header_cell(out, "target", false);
  header_cell(out, "target tris", true);
  header_cell(out, "triangles", true);
  header_cell(out, "ratio", true);
  header_cell(out, "error bound %", true);
  header_cell(out, "mean %", true);
  header_cell(out, "RMS %", true);
  header_cell(out, "Hausdorff %", true);
  header_cell(out, "normal dev \xC2\xB0", true);
  header_cell(out, "UV flips+spans", true);
  header_cell(out, "quad fraction", true);
  header_cell(out, "stop reason", false);
  header_cell(out, "time s", true);
  header_cell(out, "budget", false);
  out += "</tr></thead><tbody>\n";

  const Lod kNoLod;  // every field absent: the LOD columns of an asset without LODs
  const auto as_count = [](double v) { return count(v); };
  const auto as_ratio = [](double v) { return fixed(v, 4); };
  const auto as_percent = [](double v) { return percent(v); };
  const auto as_degrees = [](double v) { return fixed(v, 2); };
  const auto as_seconds = [](double v) { return fixed(v, 3); };
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Asset& a = *rows[i].asset;
    const Lod& l = rows[i].lod ? *rows[i].lod : kNoLod;
    out += a.failed() ? "<tr class=\"failed\"" : "<tr";
    out += " data-rank=\"" + std::to_string(i) + "\">";
    number_cell(out, static_cast<double>(i + 1), as_count);
    text_cell(out, a.path, "path");
    text_cell(out, a.class_name);
    text_cell(out, a.status, status_class(a.status));
    text_cell(out, yes_no(a.cache_hit));
    number_cell(out, l.level ? std::optional<double>(static_cast<double>(*l.level)) : std::nullopt, as_count);
    text_cell(out, target_text(l));
    number_cell(out, l.target_triangles, as_count);
    number_cell(out, l.triangles, as_count);
    number_cell(out, l.ratio, as_ratio);
    number_cell(out, l.error_bound_rel, as_percent);
    number_cell(out, l.mean_rel, as_percent);
    number_cell(out, l.rms_rel, as_percent);
    number_cell(out, l.hausdorff_rel, as_percent);
    number_cell(out, l.normal_deviation_mean_deg, as_degrees);
    number_cell(out, l.uv_problems, as_count);
    number_cell(out, l.quad_fraction, as_ratio);
    text_cell(out, l.stop_reason);
    number_cell(out, rows[i].lod ? l.seconds : a.seconds, as_seconds);  // no LODs: the asset's own time
    text_cell(out, l.budget, l.missed() ? "st-failed" : "");
    out += "</tr>\n";
  }
  out += "</tbody></table></div>\n</section>\n";
}

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

// Decades around [min, max] (both > 0), at most ~6 labelled, so a chain spanning 1e-6..1 stays readable.
Axis log_axis(double min, double max) {
  Axis a;
  a.log = true;
  int lo_exp = static_cast<int>(std::floor(std::log10(min)));
  int hi_exp = static_cast<int>(std::ceil(std::log10(max)));
  if (hi_exp <= lo_exp) hi_exp = lo_exp + 1;
  const int step = std::max(1, (hi_exp - lo_exp + 5) / 6);
  hi_exp = lo_exp + step * ((hi_exp - lo_exp + step - 1) / step);
  a.lo = std::pow(10.0, lo_exp);
  a.hi = std::pow(10.0, hi_exp);
  for (int e = lo_exp; e <= hi_exp; e += step) a.ticks.push_back(std::pow(10.0, e));
  if (step == 1 && hi_exp - lo_exp <= 3) {
    for (int e = lo_exp; e < hi_exp; ++e) {
      for (int m = 2; m <= 9; ++m) a.minor_ticks.push_back(m * std::pow(10.0, e));
    }
  }
  return a;
}

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

// Categorical colours for LOD levels (Tableau 10: distinct hues of similar weight on white); LOD1 gets the first.
constexpr std::array<std::string_view, 10> kLevelColours = {"#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f",
                                                            "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"};
constexpr std::string_view kNoLevelColour = "#555555";

std::string_view level_colour(const std::optional<std::int64_t>& level) {
  if (!level) return kNoLevelColour;
  const std::int64_t n = static_cast<std::int64_t>(kLevelColours.size());
  return kLevelColours[static_cast<std::size_t>((((*level - 1) % n) + n) % n)];
}

std::string level_label(const std::optional<std::int64_t>& level) {
  return level ? "LOD" + std::to_string(*level) : std::string("LOD ") + std::string(kDash);
}

struct Point {
  double ratio = 0;
  double mean_percent = 0;
  std::optional<std::int64_t> level;
  const Asset* asset = nullptr;
};

// Values a chart can place: the axes' arithmetic (decades, x100 for percent, nice steps) stays finite.
bool plottable(double v) {
  return v >= 1e-280 && v <= 1e280;
}

// Plot geometry, in SVG user units (the viewBox; the page scales it).
constexpr double kPlotWidth = 620, kPlotHeight = 360;
constexpr double kLeft = 64, kRight = 96, kTop = 16, kBottom = 48;  // kRight leaves room for the legend

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
// cannot place (mean error 0, or no measurement) are counted in the caption instead.
void render_class_scatter(std::string& out, const std::string& name, const std::vector<const Asset*>& assets) {
  std::vector<Point> points;
  std::size_t lods = 0;
  for (const Asset* a : assets) {
    for (const Lod& l : a->lods) {
      ++lods;
      if (l.ratio && l.mean_rel && plottable(*l.ratio) && plottable(*l.mean_rel)) {
        points.push_back({*l.ratio, *l.mean_rel * 100.0, l.level, a});
      }
    }
  }
  const std::string name_html = escaped(name);
  out += "<figure>\n<figcaption>" + name_html + " <small>" + std::to_string(assets.size()) +
         (assets.size() == 1 ? " asset, " : " assets, ") + std::to_string(lods) + (lods == 1 ? " LOD" : " LODs");
  if (points.size() < lods) {
    out += ", " + std::to_string(lods - points.size()) + " not plotted (error or ratio missing, zero or out of range)";
  }
  out += "</small></figcaption>\n";
  svg_open(out, kPlotWidth, kPlotHeight, "mean error vs triangle ratio: " + name_html);
  const double x0 = kLeft, x1 = kPlotWidth - kRight, y0 = kTop, y1 = kPlotHeight - kBottom;
  if (points.empty()) {
    out += "<rect class=\"frame\" x=\"" + px(x0) + "\" y=\"" + px(y0) + "\" width=\"" + px(x1 - x0) + "\" height=\"" +
           px(y1 - y0) + "\"/><text class=\"muted\" x=\"" + px((x0 + x1) / 2) + "\" y=\"" + px((y0 + y1) / 2) +
           "\" text-anchor=\"middle\">no measured LODs</text>\n</svg>\n</figure>\n";
    return;
  }

  double min_x = points[0].ratio, max_x = min_x, min_y = points[0].mean_percent, max_y = min_y;
  for (const Point& p : points) {
    min_x = std::min(min_x, p.ratio), max_x = std::max(max_x, p.ratio);
    min_y = std::min(min_y, p.mean_percent), max_y = std::max(max_y, p.mean_percent);
  }
  // Ratios of one class often sit within a decade (0.5, 0.25, 0.1): linear reads better there; a chain down to
  // 1% needs a log axis to separate its low LODs.
  const Axis x_axis = max_x / min_x >= 10 ? log_axis(min_x, max_x) : linear_axis_from_zero(max_x);
  const Axis y_axis = log_axis(min_y, max_y);

  axis_lines(out, x_axis, true, x0, y0, x1, y1);
  axis_lines(out, y_axis, false, x0, y0, x1, y1);
  out += "<rect class=\"frame\" x=\"" + px(x0) + "\" y=\"" + px(y0) + "\" width=\"" + px(x1 - x0) + "\" height=\"" +
         px(y1 - y0) + "\"/>\n";
  out += "<text x=\"" + px((x0 + x1) / 2) + "\" y=\"" + px(kPlotHeight - 10) + "\" text-anchor=\"middle\">" +
         "achieved triangle ratio" + (x_axis.log ? " (log)" : "") + "</text>\n";
  out += "<text x=\"14\" y=\"" + px((y0 + y1) / 2) + "\" text-anchor=\"middle\" transform=\"rotate(-90 14 " +
         px((y0 + y1) / 2) + ")\">mean error, % of diagonal (log)</text>\n";

  // Lower levels first, so the coarse LODs (fewer, and the ones a reader looks for) are drawn on top.
  std::vector<const Point*> order;
  order.reserve(points.size());
  for (const Point& p : points) order.push_back(&p);
  std::stable_sort(order.begin(), order.end(), [](const Point* a, const Point* b) { return a->level < b->level; });
  for (const Point* p : order) {
    out += "<circle cx=\"" + px(x_axis.to_pixel(p->ratio, x0, x1)) + "\" cy=\"" +
           px(y_axis.to_pixel(p->mean_percent, y1, y0)) + "\" r=\"3.5\" fill=\"" + std::string(level_colour(p->level)) +
           "\" fill-opacity=\"0.8\" stroke=\"#ffffff\" stroke-width=\"0.5\"><title>";
    append_escaped(out, p->asset->path_or_empty());
    out += ' ' + level_label(p->level) + ": ratio " + fixed(p->ratio, 4) + ", mean " + fixed(p->mean_percent, 4) +
           "%</title></circle>\n";
  }

  std::set<std::optional<std::int64_t>> levels;
  for (const Point& p : points) levels.insert(p.level);
  double y = y0 + 8;
  for (const auto& level : levels) {
    out += "<circle cx=\"" + px(x1 + 16) + "\" cy=\"" + px(y) + "\" r=\"4\" fill=\"" +
           std::string(level_colour(level)) + "\"/><text x=\"" + px(x1 + 24) + "\" y=\"" + px(y + 4) + "\">" +
           level_label(level) + "</text>\n";
    y += 16;
  }
  out += "</svg>\n</figure>\n";
}

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

void render_plots(std::string& out, const std::vector<Asset>& assets) {
  // Classes by name; assets no class matched form their own group, last, and only when they have LODs to plot.
  std::map<std::string, std::vector<const Asset*>> classes;
  std::vector<const Asset*> unclassified;
  bool unclassified_lods = false;
  for (const Asset& a : assets) {
    if (a.class_name) {
      classes[*a.class_name].push_back(&a);
    } else {
      unclassified.push_back(&a);
      unclassified_lods = unclassified_lods || !a.lods.empty();
    }
  }
  out += "<section id=\"plots\">\n<h2>Error vs triangle ratio</h2>\n";
  out +=
      "<p class=\"meta\">Measured mean distance to the source, % of its bounding-box diagonal, per LOD. Hover a "
      "dot for the asset.</p>\n<div class=\"plots\">\n";
  for (const auto& [name, members] : classes) render_class_scatter(out, name, members);
  if (unclassified_lods) render_class_scatter(out, "(no class)", unclassified);
  out += "</div>\n<div class=\"plots\">\n";
  render_worst_assets(out, assets);
  out += "</div>\n</section>\n";
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
  const std::vector<Row> rows = order_rows(assets);

  std::string out;
  out.reserve(16384 + rows.size() * 1200);
  out += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  // Self-contained by construction, and enforced: the browser refuses any load the page did not inline.
  out +=
      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'; "
      "script-src 'unsafe-inline'; img-src data:\">\n";
  out += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>lodforge report";
  if (const std::optional<std::string> config_file = text(report, "config_file")) {
    out += " \xE2\x80\x94 ";
    append_escaped(out, *config_file);
  }
  out += "</title>\n<style>";
  out += kStyle;
  out += "</style>\n</head>\n<body>\n";

  render_header(out, report);
  if (assets.empty()) {
    out += "<p class=\"empty\" id=\"no-assets\">This report has no assets.</p>\n";
  } else {
    render_failures(out, assets);
    render_lod_table(out, rows);
    render_plots(out, assets);
  }
  render_effective_config(out, report);

  out += "<script>";
  out += kScript;
  out += "</script>\n</body>\n</html>\n";
  return out;
}

}  // namespace lodforge::batch
