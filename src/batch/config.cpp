// Batch config parsing: strict, path-naming, every problem at once (PDAL's pipeline reader is the model).
//
// The options a LOD may override are one table (option_fields): key, how to read it into LodOptions with
// its checks, how to write it back. The same table drives parsing at all three levels (defaults, class
// options, LOD), the allowed-key lists in messages, and effective_config_json, so adding an option is one
// line there (plus its entry in configs/schema.json).
#include "lodforge/batch/config.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <span>
#include <sstream>
#include <utility>

namespace lodforge::batch {
namespace {

using Json = nlohmann::json;

// --- problems and JSON paths -----------------------------------------------------------------------------

// Problems found so far, each "<json path>: <problem>".
class Problems {
 public:
  void add(std::string_view path, std::string_view problem) {
    lines_.push_back((path.empty() ? std::string("(root)") : std::string(path)) + ": " + std::string(problem));
  }
  bool empty() const { return lines_.empty(); }
  std::vector<std::string> take() { return std::move(lines_); }

 private:
  std::vector<std::string> lines_;
};

// dump() throws on invalid UTF-8, which a document built in code (not parsed) may hold; messages never should.
std::string dump(const Json& v) {
  return v.dump(-1, ' ', false, Json::error_handler_t::replace);
}

bool is_identifier(std::string_view key) {
  return !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '$';
  });
}

// "a.b" for plain keys, a["odd key"] otherwise, so that every path can be read back unambiguously.
std::string child(std::string_view path, std::string_view key) {
  if (!is_identifier(key)) return std::string(path) + "[" + dump(Json(std::string(key))) + "]";
  return path.empty() ? std::string(key) : std::string(path) + "." + std::string(key);
}

std::string child(std::string_view path, std::size_t index) {
  return std::string(path) + "[" + std::to_string(index) + "]";
}

// Integral values print without ".0" ("must be < 90"); others print shortest round-trip ("0.25").
std::string format_number(double x) {
  if (std::isfinite(x) && x == std::floor(x) && std::abs(x) < 1e15) {
    return std::to_string(static_cast<long long>(x));
  }
  return dump(Json(x));
}

// What a wrong-typed value is, for "must be a number, got string \"abc\"".
std::string describe(const Json& v) {
  switch (v.type()) {
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string: {
      std::string s = dump(v);
      constexpr std::size_t kMaxShown = 40;
      if (s.size() > kMaxShown) s = s.substr(0, kMaxShown - 4) + "...\"";
      return "string " + s;
    }
    default:
      return dump(v);  // null, true/false, numbers as written
  }
}

std::string join(std::span<const std::string_view> items, std::string_view separator) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i) out += separator;
    out += items[i];
  }
  return out;
}

std::string quoted_list(std::span<const std::string_view> items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) out += (i ? ", \"" : "\"") + std::string(items[i]) + "\"";
  return out;
}

// Optimal-string-alignment distance: a swapped pair ("ratoi") counts as one edit, the commonest typo.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

// The allowed key closest to a typo, when close enough to be a plausible intent (first of ties: table order).
std::optional<std::string_view> closest_key(std::string_view key, std::span<const std::string_view> allowed) {
  const std::size_t limit = key.size() <= 3 ? 1 : 2;
  std::optional<std::string_view> best;
  std::size_t best_distance = limit + 1;
  for (std::string_view a : allowed) {
    const std::size_t distance = edit_distance(key, a);
    if (distance < best_distance) {
      best = a;
      best_distance = distance;
    }
  }
  return best;
}

// Keys people write from SimplifyOptions or the command line, answered with what to write instead.
constexpr std::pair<std::string_view, std::string_view> kRedirectedKeys[] = {
    {"threads", "not a config option: the thread count comes from `lodforge run --jobs`"},
    {"target_ratio", "not a config option: a LOD's ratio target is written \"ratio\""},
    {"target_triangles", "not a config option: a LOD's triangle target is written \"triangles\""},
    {"max_error_abs", "not a config option: write \"max_error\": {\"absolute\": x} in a LOD"},
    {"max_error_rel", "not a config option: write \"max_error\": {\"relative\": x} in a LOD"},
    {"border_mode", "not a config option: the border mode is written \"border\""},
};

// Reports every key of `object` that is not in `allowed`.
void check_keys(const Json& object, std::string_view path, std::span<const std::string_view> allowed,
                Problems& problems) {
  for (const auto& item : object.items()) {
    const std::string& key = item.key();  // not a structured binding: lambdas below capture it
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    const auto redirect = std::find_if(std::begin(kRedirectedKeys), std::end(kRedirectedKeys),
                                       [&](const auto& r) { return r.first == key; });
    if (redirect != std::end(kRedirectedKeys)) {
      problems.add(child(path, key), redirect->second);
      continue;
    }
    std::string message = "unknown key";
    if (const auto guess = closest_key(key, allowed)) message += " (did you mean \"" + std::string(*guess) + "\"?)";
    problems.add(child(path, key), message + "; allowed: " + join(allowed, ", "));
  }
}

const Json* find(const Json& object, std::string_view key) {
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

// --- typed readers: each reports its own problem and returns nullopt on failure --------------------------

// Allowed range of a number, written as at_least(0), above(0).below(90), ...
struct Bounds {
  std::optional<double> min;
  bool min_exclusive = false;
  std::optional<double> max;
  bool max_exclusive = false;

  Bounds at_most(double m) const { return with_max(m, false); }
  Bounds below(double m) const { return with_max(m, true); }

 private:
  Bounds with_max(double m, bool exclusive) const {
    Bounds b = *this;
    b.max = m;
    b.max_exclusive = exclusive;
    return b;
  }
};

Bounds at_least(double m) {
  Bounds b;
  b.min = m;
  return b;
}

Bounds above(double m) {
  Bounds b = at_least(m);
  b.min_exclusive = true;
  return b;
}

std::optional<double> read_number(const Json& v, std::string_view path, const Bounds& bounds, Problems& problems) {
  if (!v.is_number()) {
    problems.add(path, "must be a number, got " + describe(v));
    return std::nullopt;
  }
  const double x = v.get<double>();
  if (!std::isfinite(x)) {
    problems.add(path, "must be finite");
    return std::nullopt;
  }
  if (bounds.min && (x < *bounds.min || (bounds.min_exclusive && x == *bounds.min))) {
    problems.add(path, std::string("must be ") + (bounds.min_exclusive ? "> " : ">= ") + format_number(*bounds.min));
    return std::nullopt;
  }
  if (bounds.max && (x > *bounds.max || (bounds.max_exclusive && x == *bounds.max))) {
    problems.add(path, std::string("must be ") + (bounds.max_exclusive ? "< " : "<= ") + format_number(*bounds.max));
    return std::nullopt;
  }
  return x;
}

// A non-negative integer in [min, max]. JSON 5.0 is not an integer here: counts are written as counts.
std::optional<std::uint64_t> read_count(const Json& v, std::string_view path, std::uint64_t min, std::uint64_t max,
                                        Problems& problems) {
  if (!v.is_number_integer()) {
    problems.add(path, "must be an integer, got " + describe(v));
    return std::nullopt;
  }
  const bool negative = !v.is_number_unsigned() && v.get<std::int64_t>() < 0;
  const std::uint64_t x = negative ? 0 : v.get<std::uint64_t>();
  if (negative || x < min) {
    problems.add(path, min == 1 ? std::string("must be > 0") : "must be >= " + std::to_string(min));
    return std::nullopt;
  }
  if (x > max) {
    problems.add(path, "must be <= " + std::to_string(max));
    return std::nullopt;
  }
  return x;
}

std::optional<bool> read_bool(const Json& v, std::string_view path, Problems& problems) {
  if (!v.is_boolean()) {
    problems.add(path, "must be true or false, got " + describe(v));
    return std::nullopt;
  }
  return v.get<bool>();
}

std::optional<std::string> read_string(const Json& v, std::string_view path, Problems& problems) {
  if (!v.is_string()) {
    problems.add(path, "must be a string, got " + describe(v));
    return std::nullopt;
  }
  return v.get<std::string>();
}

bool expect_object(const Json& v, std::string_view path, Problems& problems) {
  if (v.is_object()) return true;
  problems.add(path, "must be an object, got " + describe(v));
  return false;
}

bool expect_array(const Json& v, std::string_view path, Problems& problems) {
  if (v.is_array()) return true;
  problems.add(path, "must be an array, got " + describe(v));
  return false;
}

template <class E>
struct EnumName {
  std::string_view name;
  E value;
};

template <class E>
std::optional<E> read_enum(const Json& v, std::string_view path, std::span<const EnumName<E>> names,
                           Problems& problems) {
  std::vector<std::string_view> spelled;
  for (const EnumName<E>& n : names) {
    if (v.is_string() && v.get<std::string>() == n.name) return n.value;
    spelled.push_back(n.name);
  }
  problems.add(path, "must be one of " + quoted_list(spelled) + ", got " + describe(v));
  return std::nullopt;
}

template <class E>
std::string_view enum_name(std::span<const EnumName<E>> names, E value) {
  for (const EnumName<E>& n : names) {
    if (n.value == value) return n.name;
  }
  return "?";
}

// --- names of enumerations: adding an engine or a mode is one line here ----------------------------------

constexpr EnumName<Engine> kEngineNames[] = {
    {"edge_collapse", Engine::edge_collapse},
    {"multiple_choice", Engine::multiple_choice},
    {"polychord", Engine::polychord},
    {"cluster", Engine::cluster},
};

constexpr EnumName<Conservative> kConservativeNames[] = {
    {"none", Conservative::none},
    {"bounding", Conservative::bounding},
    {"occluder", Conservative::occluder},
};

constexpr EnumName<BorderMode> kBorderNames[] = {
    {"free", BorderMode::free},
    {"preserve", BorderMode::preserve},
    {"lock", BorderMode::lock},
};

constexpr EnumName<SeamMode> kSeamNames[] = {
    {"keep", SeamMode::keep},
    {"relax", SeamMode::relax},
    {"relax_materials", SeamMode::relax_materials},
};

constexpr EnumName<AttributePlacement> kPlacementNames[] = {
    {"optimal", AttributePlacement::optimal},
    {"keep", AttributePlacement::keep},
};

constexpr EnumName<TilingMode> kTilingNames[] = {
    {"auto", TilingMode::automatic},
    {"on", TilingMode::on},
    {"off", TilingMode::off},
};

constexpr EnumName<symmetry::PlaneMode> kSymmetryPlaneNames[] = {
    {"auto", symmetry::PlaneMode::automatic},
    {"x", symmetry::PlaneMode::x},
    {"y", symmetry::PlaneMode::y},
    {"z", symmetry::PlaneMode::z},
    {"none", symmetry::PlaneMode::none},
};

constexpr EnumName<ReportPictures> kReportPicturesNames[] = {
    {"auto", ReportPictures::automatic},
    {"on", ReportPictures::on},
    {"off", ReportPictures::off},
};

constexpr EnumName<GltfLods> kGltfLodsNames[] = {
    {"msft_lod", GltfLods::msft_lod},
    {"files", GltfLods::files},
    {"both", GltfLods::both},
};

constexpr EnumName<LodFrom> kFromNames[] = {
    {"previous", LodFrom::previous},
    {"source", LodFrom::source},
};

// --- option tables ---------------------------------------------------------------------------------------

// One configurable key: how to read it into a Target (with its checks) and how to write it back.
template <class Target>
struct Field {
  std::string_view key;
  std::function<void(const Json&, const std::string& path, Target&, Problems&)> read;
  std::function<Json(const Target&)> write;
};

// Where a member lives in the struct a table fills: LodOptions splits into SimplifyOptions (what the
// simplifier takes today) and PendingOptions (validated now, taken later).
template <class T>
T& ref(LodOptions& o, T SimplifyOptions::*m) {
  return o.simplify.*m;
}
template <class T>
const T& ref(const LodOptions& o, T SimplifyOptions::*m) {
  return o.simplify.*m;
}
template <class T>
T& ref(LodOptions& o, T PendingOptions::*m) {
  return o.pending.*m;
}
template <class T>
const T& ref(const LodOptions& o, T PendingOptions::*m) {
  return o.pending.*m;
}
template <class S, class T>
T& ref(S& o, T S::*m) {
  return o.*m;
}
template <class S, class T>
const T& ref(const S& o, T S::*m) {
  return o.*m;
}

template <class Target>
void apply_fields(const Json& object, const std::string& path, const std::vector<Field<Target>>& fields, Target& target,
                  Problems& problems) {
  for (const Field<Target>& f : fields) {
    if (const Json* v = find(object, f.key)) f.read(*v, child(path, f.key), target, problems);
  }
}

// A field that writes null is left out (an option shown only where it is set).
template <class Target>
Json write_fields(const std::vector<Field<Target>>& fields, const Target& target) {
  Json out = Json::object();
  for (const Field<Target>& f : fields) {
    Json value = f.write(target);
    if (!value.is_null()) out[std::string(f.key)] = std::move(value);
  }
  return out;
}

template <class Target>
void append_keys(std::vector<std::string_view>& keys, const std::vector<Field<Target>>& fields) {
  for (const Field<Target>& f : fields) keys.push_back(f.key);
}

// Field builders for one Target type, so that a table line names only the key, the member and its checks.
template <class Target>
struct FieldsOf {
  template <class M>
  static Field<Target> number(std::string_view key, M member, Bounds bounds) {
    return {key,
            [=](const Json& v, const std::string& path, Target& o, Problems& p) {
              if (const auto x = read_number(v, path, bounds, p)) ref(o, member) = *x;
            },
            [=](const Target& o) { return Json(ref(o, member)); }};
  }

  template <class M>
  static Field<Target> count(std::string_view key, M member, std::uint64_t min, std::uint64_t max) {
    return {key,
            [=](const Json& v, const std::string& path, Target& o, Problems& p) {
              using T = std::remove_cvref_t<decltype(ref(o, member))>;
              if (const auto x = read_count(v, path, min, max, p)) ref(o, member) = static_cast<T>(*x);
            },
            [=](const Target& o) { return Json(ref(o, member)); }};
  }

  template <class M>
  static Field<Target> flag(std::string_view key, M member) {
    return {key,
            [=](const Json& v, const std::string& path, Target& o, Problems& p) {
              if (const auto x = read_bool(v, path, p)) ref(o, member) = *x;
            },
            [=](const Target& o) { return Json(ref(o, member)); }};
  }

  // A string with its own grammar: `problem` returns what is wrong with a value, or empty.
  template <class M>
  static Field<Target> text(std::string_view key, M member, std::string (*problem)(const std::string&)) {
    return {key,
            [=](const Json& v, const std::string& path, Target& o, Problems& p) {
              const auto x = read_string(v, path, p);
              if (!x) return;
              if (const std::string why = problem(*x); !why.empty()) {
                p.add(path, why);
              } else {
                ref(o, member) = *x;
              }
            },
            [=](const Target& o) { return Json(ref(o, member)); }};
  }

  template <class M, class E, std::size_t N>
  static Field<Target> choice(std::string_view key, M member, const EnumName<E> (&names)[N]) {
    const std::span<const EnumName<E>> all(names);
    return {key,
            [=](const Json& v, const std::string& path, Target& o, Problems& p) {
              if (const auto x = read_enum(v, path, all, p)) ref(o, member) = *x;
            },
            [=](const Target& o) { return Json(std::string(enum_name(all, ref(o, member)))); }};
  }

  // A nested object with its own table; keys it does not give keep their inherited values, so a LOD can
  // override one attribute weight and keep the class's others.
  template <class M, class Sub>
  static Field<Target> object(std::string_view key, M member, const std::vector<Field<Sub>>& (*sub_fields)()) {
    return {key,
            [=](const Json& v, const std::string& path, Target& o, Problems& p) {
              if (!expect_object(v, path, p)) return;
              std::vector<std::string_view> keys;
              append_keys(keys, sub_fields());
              check_keys(v, path, keys, p);
              apply_fields(v, path, sub_fields(), ref(o, member), p);
            },
            [=](const Target& o) { return write_fields(sub_fields(), ref(o, member)); }};
  }
};

// A painted-priority channel (simplify.hpp, is_priority_channel); the schema's pattern is the same grammar.
std::string priority_channel_problem(const std::string& s) {
  if (is_priority_channel(s)) return {};
  return "must be \"none\", a custom attribute such as \"_LOD_PRIORITY\" or \"_PAINT.x\", or a colour channel "
         "such as \"COLOR_0.r\"; got " +
         dump(Json(s));
}

const std::vector<Field<AttributeWeights>>& attribute_weight_fields() {
  using B = FieldsOf<AttributeWeights>;
  static const std::vector<Field<AttributeWeights>> fields = {
      B::number("normal", &AttributeWeights::normal, at_least(0)),
      B::number("uv", &AttributeWeights::uv, at_least(0)),
      B::number("color", &AttributeWeights::color, at_least(0)),
      B::number("skin", &AttributeWeights::skin, at_least(0)),
  };
  return fields;
}

// Conservative LODs (collision hulls, occluders) are separate outputs, never render levels of a chain: they are
// the class's `collision` and `occluder` entries. In the option levels the keys parse and only their neutral
// values are accepted; left out of the effective config at those, so that cache keys stay as they were.
constexpr std::string_view kConservativeOutputs =
    "collision and occluder LODs are separate outputs, not render levels of a LOD chain: give them as a "
    "\"collision\" or \"occluder\" entry of the class or of defaults (docs/conservative.md)";

Field<LodOptions> conservative_field() {
  return {"conservative",
          [](const Json& v, const std::string& path, LodOptions& o, Problems& p) {
            const auto x = read_enum(v, path, std::span<const EnumName<Conservative>>(kConservativeNames), p);
            if (!x) return;
            if (*x != Conservative::none)
              p.add(path, std::string(kConservativeOutputs));
            else
              o.simplify.conservative = *x;
          },
          [](const LodOptions& o) {
            return o.simplify.conservative == Conservative::none
                       ? Json()
                       : Json(std::string(enum_name(std::span<const EnumName<Conservative>>(kConservativeNames),
                                                    o.simplify.conservative)));
          }};
}

Field<LodOptions> max_volume_growth_field() {
  return {"max_volume_growth",
          [](const Json& v, const std::string& path, LodOptions& o, Problems& p) {
            const auto x = read_number(v, path, Bounds{}, p);
            if (!x) return;
            if (*x >= 0.0) {
              p.add(path,
                    "applies to collision LODs only: write it in the \"collision\" entry of the class or of "
                    "defaults (docs/conservative.md)");
            } else {
              o.simplify.max_volume_growth = *x;
            }
          },
          [](const LodOptions& o) {
            return o.simplify.max_volume_growth < 0.0 ? Json() : Json(o.simplify.max_volume_growth);
          }};
}

// Left out of the effective config at 0 (off), so that the cache keys of configs from before it stay as they were.
Field<LodOptions> symmetry_weight_field() {
  return {"symmetry_weight",
          [](const Json& v, const std::string& path, LodOptions& o, Problems& p) {
            if (const auto x = read_number(v, path, at_least(0), p)) o.simplify.symmetry_weight = *x;
          },
          [](const LodOptions& o) {
            return o.simplify.symmetry_weight == 0.0 ? Json() : Json(o.simplify.symmetry_weight);
          }};
}

// The simplifier options a config may set at every level (defaults, class options, LOD). One line each.
const std::vector<Field<LodOptions>>& option_fields() {
  using B = FieldsOf<LodOptions>;
  static const std::vector<Field<LodOptions>> fields = {
      B::choice("engine", &SimplifyOptions::engine, kEngineNames),
      B::choice("border", &SimplifyOptions::border_mode, kBorderNames),
      B::number("border_weight", &SimplifyOptions::border_weight, at_least(0)),
      B::number("regularization_weight", &SimplifyOptions::regularization_weight, at_least(0)),
      // Below 90: at 90 a sequence of collapses can fold a face over step by step without any one step
      // exceeding the threshold.
      B::number("max_flip_angle_deg", &SimplifyOptions::max_flip_angle_deg, above(0).below(90)),
      B::count("seed", &SimplifyOptions::seed, 0, std::numeric_limits<std::uint64_t>::max()),
      // The same range SimplifyOptions::validate() accepts, so that a valid config never fails there.
      B::count("multiple_choice_k", &SimplifyOptions::multiple_choice_k, 1, 256),
      B::count("max_batch", &SimplifyOptions::max_batch, 0, std::numeric_limits<std::size_t>::max()),
      B::object("attribute_weights", &SimplifyOptions::attribute_weights, &attribute_weight_fields),
      B::choice("seams", &SimplifyOptions::seams, kSeamNames),
      B::flag("permissive", &SimplifyOptions::permissive),  // deprecated alias of "seams": "relax"
      B::text("priority_channel", &SimplifyOptions::priority_channel, &priority_channel_problem),
      B::choice("attribute_placement", &SimplifyOptions::attribute_placement, kPlacementNames),
      B::number("priority_lock", &SimplifyOptions::priority_lock, above(0)),
      B::number("skin_weight_threshold", &SimplifyOptions::skin_weight_threshold, at_least(0).at_most(1)),
      B::number("skin_max_distance", &SimplifyOptions::skin_max_distance, at_least(0).at_most(2)),
      B::choice("tiling", &SimplifyOptions::tiling, kTilingNames),
      // The same lower bound SimplifyOptions::validate() sets.
      B::count("tile_triangles", &SimplifyOptions::tile_triangles, 100, std::numeric_limits<std::uint32_t>::max()),
      B::choice("cluster_stage", &SimplifyOptions::cluster_stage, kTilingNames),
      B::number("cluster_stage_factor", &SimplifyOptions::cluster_stage_factor, at_least(1)),
      symmetry_weight_field(),
      conservative_field(),
      max_volume_growth_field(),
  };
  return fields;
}

// Options of the whole asset rather than of one LOD: `defaults` and class options only.
const std::vector<Field<LodOptions>>& asset_option_fields() {
  using B = FieldsOf<LodOptions>;
  static const std::vector<Field<LodOptions>> fields = {
      B::choice("symmetry_plane", &PendingOptions::symmetry_plane, kSymmetryPlaneNames),
  };
  return fields;
}

// Output options: `defaults` only (they shape files, not LODs).
const std::vector<Field<OutputOptions>>& output_fields() {
  using B = FieldsOf<OutputOptions>;
  static const std::vector<Field<OutputOptions>> fields = {
      B::choice("gltf_lods", &OutputOptions::gltf_lods, kGltfLodsNames),
      B::flag("post_process", &OutputOptions::post_process),
      B::flag("write_source_lod0", &OutputOptions::write_source_lod0),
  };
  return fields;
}

// `defaults.lod_switch`: the projection of LOD switch points (LodSwitch).
const std::vector<Field<LodSwitch>>& lod_switch_fields() {
  using B = FieldsOf<LodSwitch>;
  static const std::vector<Field<LodSwitch>> fields = {
      B::number("screen_height_px", &LodSwitch::screen_height_px, above(0)),
      B::number("error_px", &LodSwitch::error_px, above(0)),
      B::number("fov_y_deg", &LodSwitch::fov_y_deg, above(0).below(180)),
  };
  return fields;
}

// Run limits: `defaults` only, and no part of the cache key (they bound how a run goes, not what it makes).
const std::vector<Field<RunLimits>>& limit_fields() {
  using B = FieldsOf<RunLimits>;
  static const std::vector<Field<RunLimits>> fields = {
      B::number("asset_timeout_s", &RunLimits::asset_timeout_s, at_least(0)),
  };
  return fields;
}

// Report options: `defaults` only, and no part of the cache key.
const std::vector<Field<ReportOptions>>& report_fields() {
  using B = FieldsOf<ReportOptions>;
  static const std::vector<Field<ReportOptions>> fields = {
      B::choice("report_pictures", &ReportOptions::pictures, kReportPicturesNames),
  };
  return fields;
}

constexpr std::string_view kRootKeys[] = {"$schema", "version", "description", "defaults", "default_class", "classes"};
constexpr std::string_view kClassKeys[] = {"name", "description", "match",    "options",
                                           "lods", "collision",   "occluder", "terrain"};
constexpr std::string_view kTerrainKeys[] = {"patch_cells",   "conservative", "skirts", "spacing", "height_scale",
                                             "height_offset", "nodata",       "width",  "height"};
constexpr std::string_view kTargetKeys[] = {"ratio", "triangles", "max_error", "screen_size"};
constexpr std::string_view kErrorKeys[] = {"relative", "absolute"};
constexpr std::string_view kScreenKeys[] = {"pixels", "screen_height_px", "fov_y_deg", "error_px"};

// Keys of `defaults` and a class's `options`; a LOD takes option_fields() only.
std::vector<std::string_view> option_keys() {
  std::vector<std::string_view> keys;
  append_keys(keys, option_fields());
  append_keys(keys, asset_option_fields());
  return keys;
}

// Class-level options as written back: the LOD options and the asset options.
Json class_options_json(const LodOptions& o) {
  Json out = write_fields(option_fields(), o);
  out.update(write_fields(asset_option_fields(), o));
  return out;
}

std::vector<std::string_view> defaults_keys() {
  std::vector<std::string_view> keys = option_keys();
  append_keys(keys, output_fields());
  append_keys(keys, limit_fields());
  append_keys(keys, report_fields());
  keys.push_back("lod_switch");
  keys.push_back("collision");
  keys.push_back("occluder");
  return keys;
}

std::vector<std::string_view> lod_keys() {
  std::vector<std::string_view> keys(std::begin(kTargetKeys), std::end(kTargetKeys));
  keys.push_back("from");
  append_keys(keys, option_fields());
  return keys;
}

// --- LOD targets -----------------------------------------------------------------------------------------

std::optional<LodTarget> read_max_error(const Json& v, const std::string& path, Problems& problems) {
  if (!expect_object(v, path, problems)) return std::nullopt;
  check_keys(v, path, kErrorKeys, problems);
  const Json* rel = find(v, "relative");
  const Json* abs = find(v, "absolute");
  if ((rel == nullptr) == (abs == nullptr)) {
    problems.add(path, rel ? "give only one of relative, absolute" : "needs one of relative, absolute");
    return std::nullopt;
  }
  // A relative error is a fraction of the bounding-box diagonal; beyond 1 every collapse is allowed.
  const Bounds bounds = rel ? at_least(0).at_most(1) : at_least(0);
  const auto x = read_number(rel ? *rel : *abs, child(path, rel ? "relative" : "absolute"), bounds, problems);
  if (!x) return std::nullopt;
  LodTarget t;
  t.kind = rel ? TargetKind::max_error_rel : TargetKind::max_error_abs;
  t.max_error = *x;
  return t;
}

std::optional<LodTarget> read_screen_size(const Json& v, const std::string& path, Problems& problems) {
  if (!expect_object(v, path, problems)) return std::nullopt;
  check_keys(v, path, kScreenKeys, problems);
  const std::pair<std::string_view, Bounds> specs[] = {
      {"pixels", above(0)},
      {"screen_height_px", above(0)},
      {"fov_y_deg", above(0).below(180)},
      {"error_px", at_least(0)},
  };
  double values[4] = {};
  bool ok = true;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& [key, bounds] = specs[i];
    const Json* field = find(v, key);
    std::optional<double> x;
    if (!field) {
      problems.add(child(path, key), "missing (required)");
    } else {
      x = read_number(*field, child(path, key), bounds, problems);
    }
    ok = ok && x.has_value();
    values[i] = x.value_or(0);
  }
  if (!ok) return std::nullopt;
  const ScreenSize s{.pixels = values[0], .screen_height_px = values[1], .fov_y_deg = values[2], .error_px = values[3]};
  if (s.pixels > s.screen_height_px) {
    problems.add(child(path, "pixels"), "must be <= screen_height_px " + format_number(s.screen_height_px));
    ok = false;
  }
  if (s.error_px >= s.pixels) {  // an error as large as the object on screen allows any collapse
    problems.add(child(path, "error_px"), "must be < pixels " + format_number(s.pixels));
    ok = false;
  }
  if (!ok) return std::nullopt;
  LodTarget t;
  t.kind = TargetKind::screen_size;
  t.max_error = s.max_error_rel();
  t.screen = s;
  return t;
}

std::optional<LodTarget> read_target(const Json& lod, const std::string& path, Problems& problems) {
  std::vector<std::string_view> present;
  for (std::string_view key : kTargetKeys) {
    if (find(lod, key)) present.push_back(key);
  }
  if (present.empty()) {
    problems.add(path, "needs a target: one of " + join(kTargetKeys, ", "));
    return std::nullopt;
  }
  if (present.size() > 1) {
    problems.add(path,
                 "has " + std::to_string(present.size()) + " targets (" + join(present, ", ") + "); give exactly one");
    return std::nullopt;
  }
  const std::string key(present[0]);
  const Json& v = lod[key];
  const std::string target_path = child(path, key);
  if (key == "ratio") {
    if (const auto r = read_number(v, target_path, above(0).at_most(1), problems)) {
      LodTarget t;
      t.ratio = *r;
      return t;
    }
  } else if (key == "triangles") {
    if (const auto n = read_count(v, target_path, 1, std::numeric_limits<std::size_t>::max(), problems)) {
      LodTarget t;
      t.kind = TargetKind::triangles;
      t.triangles = static_cast<std::size_t>(*n);
      return t;
    }
  } else if (key == "max_error") {
    return read_max_error(v, target_path, problems);
  } else {
    return read_screen_size(v, target_path, problems);
  }
  return std::nullopt;
}

// What the statically known part of the target means for SimplifyOptions (exact for a build from the source).
void set_source_target(SimplifyOptions& o, const LodTarget& target) {
  o.target_ratio = 1.0;
  o.target_triangles = 0;
  o.max_error_abs = -1.0;
  o.max_error_rel = -1.0;
  switch (target.kind) {
    case TargetKind::ratio:
      o.target_ratio = target.ratio;
      break;
    case TargetKind::triangles:
      o.target_triangles = target.triangles;
      break;
    case TargetKind::max_error_rel:
    case TargetKind::screen_size:
      o.max_error_rel = target.max_error;
      o.target_triangles = 1;  // the error budget decides where to stop
      break;
    case TargetKind::max_error_abs:
      o.max_error_abs = target.max_error;
      o.target_triangles = 1;
      break;
  }
}

// Monotonicity along one class's chain, per target kind: a kind is compared with the latest LOD of the same
// kind, since ratios and error budgets cannot be compared without the asset.
class ChainCheck {
 public:
  void check(const LodSpec& lod, const std::string& path, Problems& problems) {
    const LodTarget& t = lod.target;
    const bool chained = lod.from == LodFrom::previous;
    // Built from the previous LOD, an error budget can only grow: that LOD's error is already spent.
    constexpr std::string_view kWhy = " (built from the previous LOD, the error only grows)";
    switch (t.kind) {
      case TargetKind::ratio:
        if (ratio_ && !(t.ratio < *ratio_)) {
          problems.add(child(path, "ratio"), "must be < previous ratio " + format_number(*ratio_));
        }
        ratio_ = t.ratio;
        break;
      case TargetKind::triangles:
        if (triangles_ && !(t.triangles < *triangles_)) {
          problems.add(child(path, "triangles"), "must be < previous triangles " + std::to_string(*triangles_));
        }
        triangles_ = t.triangles;
        break;
      case TargetKind::max_error_rel:
      case TargetKind::max_error_abs: {
        const bool rel = t.kind == TargetKind::max_error_rel;
        std::optional<double>& last = rel ? error_rel_ : error_abs_;
        const char* unit = rel ? "relative" : "absolute";
        if (chained && last && !(t.max_error > *last)) {
          problems.add(child(child(path, "max_error"), unit), "must be > previous max_error." + std::string(unit) +
                                                                  " " + format_number(*last) + std::string(kWhy));
        }
        last = t.max_error;
        break;
      }
      case TargetKind::screen_size:
        if (pixels_ && !(t.screen.pixels < *pixels_)) {
          problems.add(child(child(path, "screen_size"), "pixels"),
                       "must be < previous pixels " + format_number(*pixels_));
        }
        if (chained && screen_error_ && !(t.max_error > *screen_error_)) {
          problems.add(child(path, "screen_size"), "error_px / pixels = " + format_number(t.max_error) +
                                                       " must be > previous " + format_number(*screen_error_) +
                                                       std::string(kWhy));
        }
        pixels_ = t.screen.pixels;
        screen_error_ = t.max_error;
        break;
    }
  }

 private:
  std::optional<double> ratio_;
  std::optional<std::size_t> triangles_;
  std::optional<double> error_rel_, error_abs_;
  std::optional<double> pixels_, screen_error_;
};

// --- document structure ----------------------------------------------------------------------------------

// A LOD; nullopt when its target is unusable (the chain check then skips it).
std::optional<LodSpec> read_lod(const Json& v, const std::string& path, const LodOptions& inherited,
                                Problems& problems) {
  if (!expect_object(v, path, problems)) return std::nullopt;
  check_keys(v, path, lod_keys(), problems);
  LodSpec lod;
  lod.options = inherited;
  const auto target = read_target(v, path, problems);
  if (const Json* from = find(v, "from")) {
    if (const auto x = read_enum<LodFrom>(*from, child(path, "from"), kFromNames, problems)) lod.from = *x;
  }
  apply_fields(v, path, option_fields(), lod.options, problems);
  if (!target) return std::nullopt;
  lod.target = *target;
  set_source_target(lod.options.simplify, lod.target);
  return lod;
}

// --- conservative LODs (collision, occluder) --------------------------------------------------------------

// A collision entry with a volume budget and no target: as few triangles as that budget allows.
LodTarget volume_only_target() {
  LodTarget t;
  t.kind = TargetKind::triangles;
  t.triangles = 1;
  return t;
}

constexpr std::string_view kConservativeTargetKeys[] = {"ratio", "triangles", "max_error"};

// The options a collision or occluder entry may override: every LOD option but the two the entry itself sets.
const std::vector<Field<LodOptions>>& conservative_option_fields() {
  static const std::vector<Field<LodOptions>> fields = [] {
    std::vector<Field<LodOptions>> out;
    for (const Field<LodOptions>& f : option_fields()) {
      if (f.key != "conservative" && f.key != "max_volume_growth") out.push_back(f);
    }
    return out;
  }();
  return fields;
}

// Keys check_keys lets through; screen_size, from and an occluder's max_volume_growth get their own message.
std::vector<std::string_view> conservative_keys() {
  std::vector<std::string_view> keys(std::begin(kConservativeTargetKeys), std::end(kConservativeTargetKeys));
  keys.push_back("max_volume_growth");
  keys.push_back("from");
  keys.push_back("screen_size");
  append_keys(keys, conservative_option_fields());
  return keys;
}

std::optional<ConservativeSpec> read_conservative(const Json& v, const std::string& path, ConservativeKind kind,
                                                  const LodOptions& inherited, Problems& problems) {
  if (!expect_object(v, path, problems)) return std::nullopt;
  check_keys(v, path, conservative_keys(), problems);
  const bool collision = kind == ConservativeKind::collision;
  ConservativeSpec spec;
  spec.kind = kind;
  spec.options = inherited;
  bool ok = true;
  apply_fields(v, path, conservative_option_fields(), spec.options, problems);
  if (const Json* from = find(v, "from")) {
    const auto x = read_enum<LodFrom>(*from, child(path, "from"), kFromNames, problems);
    if (x && *x != LodFrom::source) {
      problems.add(child(path, "from"), "a collision or occluder LOD is always built from the source");
    }
  }
  if (find(v, "screen_size")) {
    problems.add(child(path, "screen_size"),
                 "a collision or occluder LOD is never drawn, so it has no screen size; give ratio, triangles or "
                 "max_error");
    ok = false;
  }
  const Json* growth = find(v, "max_volume_growth");
  if (growth && !collision) {
    problems.add(child(path, "max_volume_growth"),
                 "applies to collision LODs only (an occluder loses volume; bound it with its target)");
    ok = false;
  } else if (growth) {
    const auto x = read_number(*growth, child(path, "max_volume_growth"), at_least(0), problems);
    ok = ok && x.has_value();
    spec.max_volume_growth_pct = x.value_or(-1);
  }
  const bool has_target = std::any_of(std::begin(kConservativeTargetKeys), std::end(kConservativeTargetKeys),
                                      [&](std::string_view k) { return find(v, k) != nullptr; });
  if (has_target && ok) {
    spec.target = read_target(v, path, problems);
    ok = spec.target.has_value();
  } else if (!has_target && !(collision && growth) && !find(v, "screen_size")) {
    problems.add(path, collision ? "needs a target: one of ratio, triangles, max_error, or a max_volume_growth"
                                 : "needs a target: one of ratio, triangles, max_error");
    ok = false;
  }
  const Engine engine = spec.options.simplify.engine;
  if (engine != Engine::edge_collapse && engine != Engine::multiple_choice) {
    const std::string name(enum_name<Engine>(kEngineNames, engine));
    if (find(v, "engine")) {
      problems.add(child(path, "engine"),
                   "a collision or occluder LOD needs a triangle engine: \"edge_collapse\" "
                   "or \"multiple_choice\", got \"" +
                       name + "\"");
    } else {
      problems.add(path, "inherits engine \"" + name +
                             "\", which cannot build collision or occluder LODs; set "
                             "\"engine\" here to \"edge_collapse\" or \"multiple_choice\"");
    }
    ok = false;
  }
  if (!ok) return std::nullopt;
  SimplifyOptions& o = spec.options.simplify;
  o.conservative = collision ? Conservative::bounding : Conservative::occluder;
  o.max_volume_growth = spec.max_volume_growth_pct >= 0 ? spec.max_volume_growth_pct / 100.0 : -1.0;
  if (spec.target) {
    set_source_target(o, *spec.target);
  } else {
    set_source_target(o, volume_only_target());  // the volume budget decides
  }
  return spec;
}

constexpr ConservativeKind kConservativeKinds[] = {ConservativeKind::collision, ConservativeKind::occluder};

// defaults.collision / defaults.occluder: checked against the defaults' options, kept as text for the classes.
void read_default_conservative(const Json& defaults, BatchConfig& config, Problems& problems) {
  for (const ConservativeKind kind : kConservativeKinds) {
    const std::string key = conservative_kind_name(kind);
    const Json* v = find(defaults, key);
    if (!v || v->is_null()) continue;
    if (read_conservative(*v, child("defaults", key), kind, config.defaults, problems)) {
      (kind == ConservativeKind::collision ? config.default_collision : config.default_occluder) = dump(*v);
    }
  }
}

// A class's own entries (null: none, whatever defaults says), else the defaults' read against its options.
void read_class_conservative(const Json& v, const std::string& path, const BatchConfig& config, AssetClass& cls,
                             Problems& problems) {
  for (const ConservativeKind kind : kConservativeKinds) {
    const std::string key = conservative_kind_name(kind);
    std::optional<ConservativeSpec> spec;
    if (const Json* own = find(v, key)) {
      if (own->is_null()) continue;
      spec = read_conservative(*own, child(path, key), kind, cls.options, problems);
    } else {
      const std::string& text =
          kind == ConservativeKind::collision ? config.default_collision : config.default_occluder;
      if (text.empty()) continue;
      Problems inherited;
      spec = read_conservative(Json::parse(text), child("defaults", key), kind, cls.options, inherited);
      for (const std::string& line : inherited.take()) problems.add(path, "with this class's options, " + line);
    }
    if (spec) cls.conservative.push_back(std::move(*spec));
  }
}

void read_match(const Json& v, const std::string& path, AssetClass& cls, Problems& problems) {
  if (!expect_array(v, path, problems)) return;
  if (v.empty()) problems.add(path, "must not be empty");
  for (std::size_t j = 0; j < v.size(); ++j) {
    const auto pattern = read_string(v[j], child(path, j), problems);
    if (!pattern) continue;
    try {
      cls.match.push_back(Glob::compile(*pattern));
    } catch (const std::invalid_argument& e) {
      problems.add(child(path, j), "invalid glob " + dump(Json(*pattern)) + ": " + e.what());
    }
  }
}

void read_lods(const Json& v, const std::string& path, AssetClass& cls, Problems& problems) {
  if (!expect_array(v, path, problems)) return;
  if (v.empty()) problems.add(path, "must not be empty");
  if (v.size() > kMaxLods) {
    problems.add(path, "has " + std::to_string(v.size()) + " LODs; at most " + std::to_string(kMaxLods));
  }
  ChainCheck chain;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::string lod_path = child(path, i);
    auto lod = read_lod(v[i], lod_path, cls.options, problems);
    if (!lod) continue;
    chain.check(*lod, lod_path, problems);
    cls.lods.push_back(std::move(*lod));
  }
}

TerrainSpec read_terrain(const Json& v, const std::string& path, Problems& problems) {
  TerrainSpec t;
  if (!expect_object(v, path, problems)) return t;
  check_keys(v, path, kTerrainKeys, problems);
  if (const Json* x = find(v, "patch_cells")) {
    if (const auto n = read_count(*x, child(path, "patch_cells"), 2, 4096, problems)) t.patch_cells = *n;
  }
  if (const Json* x = find(v, "conservative")) {
    const auto mode = read_enum(*x, child(path, "conservative"),
                                std::span<const EnumName<Conservative>>(kConservativeNames), problems);
    if (mode) t.conservative = *mode;
  }
  if (const Json* x = find(v, "skirts")) {
    if (const auto b = read_bool(*x, child(path, "skirts"), problems)) t.skirts = *b;
  }
  if (const Json* x = find(v, "spacing")) {
    const std::string sp = child(path, "spacing");
    if (x->is_array() && x->size() == 2) {
      const auto sx = read_number((*x)[0], child(sp, 0), above(0), problems);
      const auto sz = read_number((*x)[1], child(sp, 1), above(0), problems);
      if (sx && sz) {
        t.layout.spacing_x = *sx;
        t.layout.spacing_z = *sz;
      }
    } else if (x->is_number()) {
      if (const auto d = read_number(*x, sp, above(0), problems)) t.layout.spacing_x = t.layout.spacing_z = *d;
    } else {
      problems.add(sp, "must be a number or [x, z], got " + describe(*x));
    }
  }
  if (const Json* x = find(v, "height_scale")) {
    if (const auto d = read_number(*x, child(path, "height_scale"), Bounds{}, problems)) t.layout.height_scale = *d;
  }
  if (const Json* x = find(v, "height_offset")) {
    if (const auto d = read_number(*x, child(path, "height_offset"), Bounds{}, problems)) t.layout.height_offset = *d;
  }
  if (const Json* x = find(v, "nodata")) {
    if (const auto n = read_count(*x, child(path, "nodata"), 0, 65535, problems)) {
      t.layout.nodata = static_cast<std::uint16_t>(*n);
    }
  }
  if (const Json* x = find(v, "width")) {
    if (const auto n = read_count(*x, child(path, "width"), 2, 1u << 20, problems)) t.layout.width = *n;
  }
  if (const Json* x = find(v, "height")) {
    if (const auto n = read_count(*x, child(path, "height"), 2, 1u << 20, problems)) t.layout.height = *n;
  }
  for (const std::string& line : t.layout.validate()) problems.add(path, line);
  return t;
}

Json terrain_json(const TerrainSpec& t) {
  Json out = {{"patch_cells", t.patch_cells},
              {"conservative",
               std::string(enum_name(std::span<const EnumName<Conservative>>(kConservativeNames), t.conservative))},
              {"skirts", t.skirts},
              {"spacing", Json::array({t.layout.spacing_x, t.layout.spacing_z})},
              {"height_scale", t.layout.height_scale},
              {"height_offset", t.layout.height_offset}};
  if (t.layout.nodata) out["nodata"] = *t.layout.nodata;
  if (t.layout.width) out["width"] = t.layout.width;
  if (t.layout.height) out["height"] = t.layout.height;
  return out;
}

// A terrain class: ratio targets only, no collision or occluder entries of its own (those inherited from
// `defaults` do not apply to it).
void check_terrain_class(const Json& v, const std::string& path, AssetClass& cls, Problems& problems) {
  for (std::size_t i = 0; i < cls.lods.size(); ++i) {
    if (cls.lods[i].target.kind != TargetKind::ratio) {
      problems.add(child(child(path, "lods"), i),
                   "a terrain class takes ratio targets only (each a fraction of a full patch's triangles)");
    }
  }
  for (const ConservativeKind kind : kConservativeKinds) {
    const Json* own = find(v, conservative_kind_name(kind));
    if (own != nullptr && !own->is_null()) {
      problems.add(child(path, conservative_kind_name(kind)),
                   "a terrain class has no collision or occluder entries: \"terrain.conservative\" sets its "
                   "patches' mode");
    }
  }
  cls.conservative.clear();
}

std::optional<AssetClass> read_class(const Json& v, const std::string& path, const BatchConfig& config,
                                     Problems& problems) {
  const LodOptions& defaults = config.defaults;
  if (!expect_object(v, path, problems)) return std::nullopt;
  check_keys(v, path, kClassKeys, problems);
  AssetClass cls;
  cls.options = defaults;
  if (const Json* name = find(v, "name")) {
    if (const auto x = read_string(*name, child(path, "name"), problems)) {
      if (x->empty()) problems.add(child(path, "name"), "must not be empty");
      cls.name = *x;
    }
  } else {
    problems.add(child(path, "name"), "missing (required)");
  }
  if (const Json* description = find(v, "description")) {
    cls.description = read_string(*description, child(path, "description"), problems).value_or("");
  }
  if (const Json* match = find(v, "match")) {
    read_match(*match, child(path, "match"), cls, problems);
  } else {
    problems.add(child(path, "match"), "missing (required)");
  }
  // Class options first: every LOD starts from them, wherever "options" sits in the object.
  if (const Json* options = find(v, "options")) {
    const std::string options_path = child(path, "options");
    if (expect_object(*options, options_path, problems)) {
      check_keys(*options, options_path, option_keys(), problems);
      apply_fields(*options, options_path, option_fields(), cls.options, problems);
      apply_fields(*options, options_path, asset_option_fields(), cls.options, problems);
    }
  }
  if (const Json* lods = find(v, "lods")) {
    read_lods(*lods, child(path, "lods"), cls, problems);
  } else {
    problems.add(child(path, "lods"), "missing (required)");
  }
  read_class_conservative(v, path, config, cls, problems);
  if (const Json* terrain = find(v, "terrain")) {
    cls.terrain = read_terrain(*terrain, child(path, "terrain"), problems);
    check_terrain_class(v, path, cls, problems);
  }
  return cls;
}

void read_classes(const Json& v, BatchConfig& config, Problems& problems) {
  if (!expect_array(v, "classes", problems)) return;
  if (v.empty()) problems.add("classes", "must not be empty");
  std::map<std::string, std::size_t> first_index;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::string path = child("classes", i);
    auto cls = read_class(v[i], path, config, problems);
    if (!cls) continue;
    if (!cls->name.empty()) {
      const auto [it, inserted] = first_index.emplace(cls->name, i);
      if (!inserted) {
        problems.add(child(path, "name"), "duplicate class name " + dump(Json(cls->name)) + " (first at " +
                                              child("classes", it->second) + ")");
      }
    }
    config.classes.push_back(std::move(*cls));
  }
}

BatchConfig read_document(const Json& doc, Problems& problems) {
  BatchConfig config;
  if (!expect_object(doc, "", problems)) return config;
  check_keys(doc, "", kRootKeys, problems);
  if (const Json* schema = find(doc, "$schema")) read_string(*schema, "$schema", problems);
  if (const Json* version = find(doc, "version")) {
    if (const auto x = read_count(*version, "version", 0, std::numeric_limits<std::uint64_t>::max(), problems)) {
      if (*x != static_cast<std::uint64_t>(kConfigVersion)) {
        problems.add("version", "unsupported version " + std::to_string(*x) + "; this lodforge reads version " +
                                    std::to_string(kConfigVersion));
      }
    }
  } else {
    problems.add("version", "missing (required)");
  }
  if (const Json* description = find(doc, "description")) {
    config.description = read_string(*description, "description", problems).value_or("");
  }
  if (const Json* defaults = find(doc, "defaults")) {
    if (expect_object(*defaults, "defaults", problems)) {
      check_keys(*defaults, "defaults", defaults_keys(), problems);
      apply_fields(*defaults, "defaults", option_fields(), config.defaults, problems);
      apply_fields(*defaults, "defaults", asset_option_fields(), config.defaults, problems);
      apply_fields(*defaults, "defaults", output_fields(), config.output, problems);
      apply_fields(*defaults, "defaults", limit_fields(), config.limits, problems);
      apply_fields(*defaults, "defaults", report_fields(), config.report, problems);
      if (const Json* sw = find(*defaults, "lod_switch"); sw && expect_object(*sw, "defaults.lod_switch", problems)) {
        std::vector<std::string_view> keys;
        append_keys(keys, lod_switch_fields());
        check_keys(*sw, "defaults.lod_switch", keys, problems);
        apply_fields(*sw, "defaults.lod_switch", lod_switch_fields(), config.lod_switch, problems);
      }
      read_default_conservative(*defaults, config, problems);
    }
  }
  if (const Json* classes = find(doc, "classes")) {
    read_classes(*classes, config, problems);
  } else {
    problems.add("classes", "missing (required)");
  }
  if (const Json* fallback = find(doc, "default_class")) {
    if (const auto name = read_string(*fallback, "default_class", problems)) {
      std::vector<std::string_view> names;
      for (const AssetClass& c : config.classes) names.push_back(c.name);
      if (std::find(names.begin(), names.end(), *name) == names.end()) {
        problems.add("default_class", "no class named " + dump(Json(*name)) + " (classes: " + join(names, ", ") + ")");
      }
      config.default_class = *name;
    }
  }
  return config;
}

// --- file reading: syntax errors and duplicate keys ------------------------------------------------------

// A SAX pass that tracks the JSON path, so that syntax errors and duplicate keys (which the DOM silently
// collapses) are reported where they are, like every other problem.
class KeyChecker final : public nlohmann::json_sax<Json> {
 public:
  explicit KeyChecker(Problems& problems) : problems_(problems) {}

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override {
    frames_.push_back({});
    return true;
  }
  bool key(string_t& key) override {
    Frame& f = frames_.back();
    f.key = key;
    f.has_key = true;
    if (!f.seen.insert(key).second) problems_.add(path(), "duplicate key");
    return true;
  }
  bool end_object() override {
    frames_.pop_back();
    return value();
  }
  bool start_array(std::size_t) override {
    frames_.emplace_back().is_array = true;
    return true;
  }
  bool end_array() override {
    frames_.pop_back();
    return value();
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    // nlohmann says "[json.exception.parse_error.101] parse error at line 3, column 5: <detail>".
    std::string what = e.what();
    constexpr std::string_view kPrefix = "parse error ";
    if (const std::size_t at = what.find(kPrefix); at != std::string::npos) what = what.substr(at + kPrefix.size());
    syntax_error_ = "invalid JSON " + what;
    syntax_path_ = path();
    return false;
  }

  const std::optional<std::string>& syntax_error() const { return syntax_error_; }
  const std::string& syntax_path() const { return syntax_path_; }

 private:
  struct Frame {
    bool is_array = false;
    std::size_t index = 0;  // array: the element being read
    bool has_key = false;   // object: the member being read
    std::string key;
    std::set<std::string> seen;
  };

  // A value is complete: an array moves to its next element; an object waits for its next key, so that an
  // error between members names the object rather than the member before it.
  bool value() {
    if (frames_.empty()) return true;
    Frame& f = frames_.back();
    if (f.is_array) {
      ++f.index;
    } else {
      f.has_key = false;
    }
    return true;
  }

  std::string path() const {
    std::string p;
    for (const Frame& f : frames_) {
      if (f.is_array) {
        p = child(p, f.index);
      } else if (f.has_key) {
        p = child(p, f.key);
      }
    }
    return p;
  }

  Problems& problems_;
  std::vector<Frame> frames_;
  std::optional<std::string> syntax_error_;
  std::string syntax_path_;
};

std::string join_problems(const std::string& source, const std::vector<std::string>& problems) {
  std::string out;
  for (const std::string& p : problems) {
    if (!out.empty()) out += '\n';
    out.append(source).append(": ").append(p);
  }
  return out;
}

Json target_json(const LodTarget& t) {
  switch (t.kind) {
    case TargetKind::ratio:
      return {{"ratio", t.ratio}};
    case TargetKind::triangles:
      return {{"triangles", t.triangles}};
    case TargetKind::max_error_rel:
      return {{"max_error", {{"relative", t.max_error}}}};
    case TargetKind::max_error_abs:
      return {{"max_error", {{"absolute", t.max_error}}}};
    case TargetKind::screen_size:
      return {{"screen_size",
               {{"pixels", t.screen.pixels},
                {"screen_height_px", t.screen.screen_height_px},
                {"fov_y_deg", t.screen.fov_y_deg},
                {"error_px", t.screen.error_px}}}};
  }
  return Json::object();
}

// symmetry_weight is left out at 0 (symmetry_weight_field); where a level turns off what its parent set, it
// says so, so that the document parses back to the same config.
void write_symmetry_override(Json& j, const LodOptions& o, const LodOptions& parent) {
  if (o.simplify.symmetry_weight != parent.simplify.symmetry_weight) j["symmetry_weight"] = o.simplify.symmetry_weight;
}

Json class_json(const AssetClass& cls) {
  Json out = {{"name", cls.name}, {"options", class_options_json(cls.options)}};
  if (!cls.description.empty()) out["description"] = cls.description;
  Json match = Json::array();
  for (const Glob& g : cls.match) match.push_back(g.pattern());
  out["match"] = std::move(match);
  Json lods = Json::array();
  for (const LodSpec& lod : cls.lods) {
    Json j = write_fields(option_fields(), lod.options);
    write_symmetry_override(j, lod.options, cls.options);
    j.update(target_json(lod.target));
    j["from"] = std::string(enum_name<LodFrom>(kFromNames, lod.from));
    lods.push_back(std::move(j));
  }
  out["lods"] = std::move(lods);
  for (const ConservativeSpec& spec : cls.conservative) {
    Json j = write_fields(conservative_option_fields(), spec.options);
    write_symmetry_override(j, spec.options, cls.options);
    if (spec.target) j.update(target_json(*spec.target));
    if (spec.max_volume_growth_pct >= 0) j["max_volume_growth"] = spec.max_volume_growth_pct;
    out[conservative_kind_name(spec.kind)] = std::move(j);
  }
  if (cls.terrain) out["terrain"] = terrain_json(*cls.terrain);
  return out;
}

}  // namespace

ConfigError::ConfigError(std::string source, std::vector<std::string> problems)
    : std::runtime_error(join_problems(source, problems)), source_(std::move(source)), problems_(std::move(problems)) {}

const char* conservative_kind_name(ConservativeKind kind) {
  return kind == ConservativeKind::collision ? "collision" : "occluder";
}

const char* target_kind_name(TargetKind kind) {
  switch (kind) {
    case TargetKind::ratio:
      return "ratio";
    case TargetKind::triangles:
      return "triangles";
    case TargetKind::max_error_rel:
      return "max_error.relative";
    case TargetKind::max_error_abs:
      return "max_error.absolute";
    case TargetKind::screen_size:
      return "screen_size";
  }
  return "?";
}

double ScreenSize::switch_distance(double radius) const {
  return distance_for_coverage(radius, screen_coverage(), fov_y_deg);
}

double coverage_for_error(double error_rel, double error_px, double screen_height_px) {
  return error_px / (screen_height_px * std::max(error_rel, 1e-12));  // an exact LOD would switch at once
}

double distance_for_coverage(double radius, double coverage, double fov_y_deg) {
  const double half_fov = fov_y_deg * std::numbers::pi / 360.0;
  if (!(coverage > 0)) return std::numeric_limits<double>::infinity();
  return radius / (coverage * std::tan(half_fov));
}

bool AssetClass::matches(std::string_view relative_path) const {
  return std::any_of(match.begin(), match.end(), [&](const Glob& g) { return g.matches(relative_path); });
}

BatchConfig parse_config(const nlohmann::json& document, std::string_view source) {
  Problems problems;
  BatchConfig config = read_document(document, problems);
  if (!problems.empty()) throw ConfigError(std::string(source), problems.take());
  return config;
}

BatchConfig load_config(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw ConfigError(source, {std::filesystem::exists(path, ec) ? "not a regular file" : "no such file"});
  }
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) throw ConfigError(source, {"cannot read the file"});

  Problems problems;
  KeyChecker checker(problems);
  if (!Json::sax_parse(text.str(), &checker)) {
    Problems syntax;
    syntax.add(checker.syntax_path(), checker.syntax_error().value_or("invalid JSON"));
    throw ConfigError(source, syntax.take());
  }
  BatchConfig config = read_document(Json::parse(text.str()), problems);
  if (!problems.empty()) throw ConfigError(source, problems.take());
  return config;
}

nlohmann::json effective_config_json(const BatchConfig& config) {
  Json defaults = class_options_json(config.defaults);
  defaults.update(write_fields(output_fields(), config.output));
  defaults.update(write_fields(limit_fields(), config.limits));
  defaults.update(write_fields(report_fields(), config.report));
  defaults["lod_switch"] = write_fields(lod_switch_fields(), config.lod_switch);
  if (!config.default_collision.empty()) defaults["collision"] = Json::parse(config.default_collision);
  if (!config.default_occluder.empty()) defaults["occluder"] = Json::parse(config.default_occluder);
  Json out = {{"version", config.version}, {"defaults", std::move(defaults)}};
  if (!config.description.empty()) out["description"] = config.description;
  if (!config.default_class.empty()) out["default_class"] = config.default_class;
  Json classes = Json::array();
  for (const AssetClass& cls : config.classes) {
    Json j = class_json(cls);
    write_symmetry_override(j["options"], cls.options, config.defaults);
    // A class that declined the defaults' entry says so, so that the document parses back to the same config.
    if (!config.default_collision.empty() && !j.contains("collision")) j["collision"] = nullptr;
    if (!config.default_occluder.empty() && !j.contains("occluder")) j["occluder"] = nullptr;
    classes.push_back(std::move(j));
  }
  out["classes"] = std::move(classes);
  return out;
}

nlohmann::json effective_class_json(const BatchConfig& config, const AssetClass& cls) {
  Json out = {{"class", class_json(cls)}, {"output", write_fields(output_fields(), config.output)}};
  // The switch projection shapes the glTF coverage hints; only a changed one joins the key, so caches made
  // before it existed stay valid.
  if (config.lod_switch != LodSwitch{}) out["lod_switch"] = write_fields(lod_switch_fields(), config.lod_switch);
  return out;
}

const AssetClass* find_class(const BatchConfig& config, std::string_view name) {
  for (const AssetClass& cls : config.classes) {
    if (cls.name == name) return &cls;
  }
  return nullptr;
}

const AssetClass* match_class(const BatchConfig& config, std::string_view relative_path) {
  for (const AssetClass& cls : config.classes) {
    if (cls.matches(relative_path)) return &cls;
  }
  return config.default_class.empty() ? nullptr : find_class(config, config.default_class);
}

std::string unmatched_reason(const BatchConfig& config, std::string_view relative_path) {
  std::vector<std::string_view> names;
  for (const AssetClass& cls : config.classes) names.push_back(cls.name);
  return dump(Json(std::string(relative_path))) + " matches no class (" + join(names, ", ") +
         ") and the config sets no default_class";
}

SimplifyOptions simplify_options_for(const LodSpec& lod, const LodInput& input) {
  SimplifyOptions o = lod.options.simplify;
  o.symmetry_plane = lod.options.pending.symmetry_plane;
  o.target_ratio = 1.0;
  o.target_triangles = 0;
  o.max_error_abs = -1.0;
  o.max_error_rel = -1.0;
  const double spent = lod.from == LodFrom::previous ? input.accumulated_error_abs : 0.0;
  switch (lod.target.kind) {
    case TargetKind::ratio: {
      // A count of the source, so a chain's ratios mean the same whichever LOD they start from.
      const double count = std::round(lod.target.ratio * static_cast<double>(input.source_triangles));
      o.target_triangles = std::max<std::size_t>(1, static_cast<std::size_t>(count));
      break;
    }
    case TargetKind::triangles:
      o.target_triangles = lod.target.triangles;
      break;
    case TargetKind::max_error_rel:
    case TargetKind::screen_size:
      o.max_error_abs = std::max(0.0, lod.target.max_error * input.source_diagonal - spent);
      o.target_triangles = 1;
      break;
    case TargetKind::max_error_abs:
      o.max_error_abs = std::max(0.0, lod.target.max_error - spent);
      o.target_triangles = 1;
      break;
  }
  return o;
}

SimplifyOptions simplify_options_for(const ConservativeSpec& spec, const LodInput& input) {
  LodSpec lod{.target = spec.target.value_or(volume_only_target()), .from = LodFrom::source, .options = spec.options};
  return simplify_options_for(lod, LodInput{.source_triangles = input.source_triangles,
                                            .source_diagonal = input.source_diagonal,
                                            .accumulated_error_abs = 0});
}

}  // namespace lodforge::batch
