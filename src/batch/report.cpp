#include "lodforge/batch/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <cstdio>
#include <stdexcept>

#include "lodforge/batch/report_html.hpp"
#include "lodforge/io/file.hpp"

namespace lodforge::batch {
namespace {

using Json = nlohmann::json;

std::uint64_t count(const Json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number_integer()) return 0;
  const std::int64_t v = it->get<std::int64_t>();
  return v > 0 ? static_cast<std::uint64_t>(v) : 0;
}

// The shape as data: per key, what its value must be. A checker walks it, so the comment at the top of
// report.hpp and this table are the two places that define the format.
enum class Kind { string, string_or_null, integer, integer_or_null, number, number_or_null, boolean, object };

struct Field {
  const char* key;
  Kind kind;
};

constexpr Field kTopFields[] = {{"lodforge_version", Kind::string},
                                {"config_file", Kind::string},
                                {"effective_config", Kind::object},
                                {"jobs", Kind::integer},
                                {"shard", Kind::string_or_null}};
constexpr Field kSummaryFields[] = {
    {"assets", Kind::integer},          {"succeeded", Kind::integer},        {"failed", Kind::integer},
    {"skipped", Kind::integer},         {"cache_hits", Kind::integer},       {"lods", Kind::integer},
    {"input_triangles", Kind::integer}, {"output_triangles", Kind::integer}, {"seconds", Kind::number}};
constexpr Field kAssetFields[] = {{"path", Kind::string},       {"class", Kind::string_or_null},
                                  {"status", Kind::string},     {"error", Kind::string_or_null},
                                  {"cache_hit", Kind::boolean}, {"seconds", Kind::number}};
constexpr Field kInputFields[] = {
    {"triangles", Kind::integer}, {"vertices", Kind::integer}, {"diagonal", Kind::number}};
// input.symmetry, when present (reports of earlier versions lack it); "plane" is checked apart.
constexpr Field kSymmetryFields[] = {{"plane_mode", Kind::string},
                                     {"symmetric_edges", Kind::integer},
                                     {"edges", Kind::integer},
                                     {"fraction", Kind::number}};
constexpr Field kLodFields[] = {{"level", Kind::integer},
                                {"from", Kind::string},
                                {"target_triangles", Kind::integer_or_null},
                                {"triangles", Kind::integer},
                                {"vertices", Kind::integer},
                                {"ratio", Kind::number},
                                {"error_bound_abs", Kind::number},
                                {"error_bound_rel", Kind::number},
                                {"mean_rel", Kind::number},
                                {"rms_rel", Kind::number},
                                {"hausdorff_rel", Kind::number},
                                {"normal_deviation_mean_deg", Kind::number},
                                {"attributes", Kind::object},
                                {"quad_fraction", Kind::number},
                                {"irregular_vertices", Kind::integer},
                                {"stop_reason", Kind::string},
                                {"seconds", Kind::number},
                                {"screen_coverage", Kind::number_or_null}};

// assets[].conservative_lods[], when present (assets of classes with collision or occluder LODs).
constexpr Field kConservativeFields[] = {{"kind", Kind::string},
                                         {"mode", Kind::string},
                                         {"target", Kind::object},
                                         {"target_triangles", Kind::integer_or_null},
                                         {"max_volume_growth_pct", Kind::number_or_null},
                                         {"triangles", Kind::integer},
                                         {"vertices", Kind::integer},
                                         {"ratio", Kind::number},
                                         {"error_bound_abs", Kind::number},
                                         {"error_bound_rel", Kind::number},
                                         {"budget", Kind::object},
                                         {"mean_rel", Kind::number},
                                         {"rms_rel", Kind::number},
                                         {"hausdorff_rel", Kind::number},
                                         {"volume_change_pct", Kind::number_or_null},
                                         {"collapses_refused", Kind::integer},
                                         {"stop_reason", Kind::string},
                                         {"gltf_node_suffix", Kind::string_or_null}};

bool has_kind(const Json& v, Kind kind) {
  switch (kind) {
    case Kind::string:
      return v.is_string();
    case Kind::string_or_null:
      return v.is_string() || v.is_null();
    case Kind::integer:
      return v.is_number_integer();
    case Kind::integer_or_null:
      return v.is_number_integer() || v.is_null();
    case Kind::number:
      return v.is_number();
    case Kind::number_or_null:
      return v.is_number() || v.is_null();
    case Kind::boolean:
      return v.is_boolean();
    case Kind::object:
      return v.is_object();
  }
  return false;
}

const char* kind_name(Kind kind) {
  switch (kind) {
    case Kind::string:
      return "a string";
    case Kind::string_or_null:
      return "a string or null";
    case Kind::integer:
      return "an integer";
    case Kind::integer_or_null:
      return "an integer or null";
    case Kind::number:
      return "a number";
    case Kind::number_or_null:
      return "a number or null";
    case Kind::boolean:
      return "true or false";
    case Kind::object:
      return "an object";
  }
  return "?";
}

template <std::size_t N>
void check_fields(const Json& obj, const Field (&fields)[N], const std::string& where, std::vector<std::string>& out) {
  if (!obj.is_object()) {
    out.push_back(where + ": expected an object");
    return;
  }
  std::set<std::string> known;
  for (const Field& f : fields) {
    known.insert(f.key);
    const auto it = obj.find(f.key);
    if (it == obj.end()) {
      out.push_back((where.empty() ? "" : where + ".") + f.key + ": missing");
    } else if (!has_kind(*it, f.kind)) {
      out.push_back((where.empty() ? "" : where + ".") + f.key + ": expected " + kind_name(f.kind));
    }
  }
  (void)known;
}

void strip_seconds(Json& j) {
  if (j.is_object()) {
    j.erase("seconds");
    for (auto& [key, value] : j.items()) strip_seconds(value);
  } else if (j.is_array()) {
    for (Json& v : j) strip_seconds(v);
  }
}

}  // namespace

Json report_summary(const Json& assets, double seconds) {
  std::uint64_t ok = 0, failed = 0, skipped = 0, not_started = 0, hits = 0, lods = 0, in_tris = 0, out_tris = 0,
                missed = 0, conservative = 0, conservative_missed = 0;
  for (const Json& a : assets) {
    const std::string status = a.value("status", std::string());
    if (status == "ok") {
      ++ok;
      in_tris += a.contains("input") ? count(a["input"], "triangles") : 0;
      if (const auto it = a.find("lods"); it != a.end() && it->is_array()) {
        lods += it->size();
        for (const Json& l : *it) {
          out_tris += count(l, "triangles");
          const auto b = l.find("budget");
          missed += b != l.end() && b->is_object() && b->value("status", std::string()) == "missed";
        }
      }
      // Collision and occluder LODs are no render level: counted apart, and not in output_triangles.
      if (const auto it = a.find("conservative_lods"); it != a.end() && it->is_array()) {
        conservative += it->size();
        for (const Json& l : *it) {
          const auto b = l.find("budget");
          conservative_missed += b != l.end() && b->is_object() && b->value("status", std::string()) == "missed";
        }
      }
    } else if (status == "failed") {
      ++failed;
    } else if (status == "not_started") {
      ++not_started;
    } else {
      ++skipped;
    }
    if (a.value("cache_hit", false)) ++hits;
  }
  Json summary = {{"assets", assets.size()}, {"succeeded", ok}, {"failed", failed},           {"skipped", skipped},
                  {"cache_hits", hits},      {"lods", lods},    {"input_triangles", in_tris}, {"output_triangles", out_tris},
                  {"seconds", seconds},      {"lods_missed", missed},   {"not_started", not_started}};
  if (conservative > 0) {
    summary["conservative_lods"] = conservative;
    summary["conservative_lods_missed"] = conservative_missed;
  }
  return summary;
}

std::vector<std::string> check_report(const Json& report) {
  std::vector<std::string> out;
  check_fields(report, kTopFields, "", out);
  if (!report.is_object()) return out;
  if (!report.contains("summary")) {
    out.push_back("summary: missing");
  } else {
    check_fields(report["summary"], kSummaryFields, "summary", out);
  }
  if (!report.contains("assets") || !report["assets"].is_array()) {
    out.push_back("assets: expected an array");
    return out;
  }
  const Json& assets = report["assets"];
  for (std::size_t i = 0; i < assets.size(); ++i) {
    const std::string where = "assets[" + std::to_string(i) + "]";
    const Json& a = assets[i];
    check_fields(a, kAssetFields, where, out);
    if (!a.is_object()) continue;
    const std::string status = a.value("status", std::string());
    if (status != "ok" && status != "failed" && status != "skipped" && status != "not_started") {
      out.push_back(where + ".status: expected ok, failed, skipped or not_started");
    }
    if (i > 0 && assets[i - 1].is_object() &&
        a.value("path", std::string()) <= assets[i - 1].value("path", std::string())) {
      out.push_back(where + ".path: assets are not sorted by path (or a path repeats)");
    }
    if (!a.contains("input")) {
      out.push_back(where + ".input: missing");
    } else {
      check_fields(a["input"], kInputFields, where + ".input", out);
      if (a["input"].is_object() && a["input"].contains("symmetry")) {
        const Json& sym = a["input"]["symmetry"];
        check_fields(sym, kSymmetryFields, where + ".input.symmetry", out);
        const bool plane_ok = sym.is_object() && sym.contains("plane") &&
                              (sym["plane"].is_null() || (sym["plane"].is_array() && sym["plane"].size() == 4 &&
                                                          std::all_of(sym["plane"].begin(), sym["plane"].end(),
                                                                      [](const Json& x) { return x.is_number(); })));
        if (!plane_ok) out.push_back(where + ".input.symmetry.plane: expected 4 numbers or null");
      }
    }
    if (!a.contains("outputs") || !a["outputs"].is_array() ||
        !std::all_of(a["outputs"].begin(), a["outputs"].end(), [](const Json& o) { return o.is_string(); })) {
      out.push_back(where + ".outputs: expected an array of strings");
    }
    if (a.contains("conservative_lods")) {
      if (!a["conservative_lods"].is_array()) {
        out.push_back(where + ".conservative_lods: expected an array");
      } else {
        for (std::size_t k = 0; k < a["conservative_lods"].size(); ++k) {
          const Json& l = a["conservative_lods"][k];
          const std::string lw = where + ".conservative_lods[" + std::to_string(k) + "]";
          check_fields(l, kConservativeFields, lw, out);
          if (!l.is_object()) continue;
          const std::string kind = l.value("kind", std::string());
          if (kind != "collision" && kind != "occluder") out.push_back(lw + ".kind: expected collision or occluder");
          if (!l.contains("outputs") || !l["outputs"].is_array()) out.push_back(lw + ".outputs: expected an array");
        }
      }
    }
    if (!a.contains("lods") || !a["lods"].is_array()) {
      out.push_back(where + ".lods: expected an array");
      continue;
    }
    for (std::size_t k = 0; k < a["lods"].size(); ++k) {
      const Json& l = a["lods"][k];
      const std::string lw = where + ".lods[" + std::to_string(k) + "]";
      check_fields(l, kLodFields, lw, out);
      if (!l.is_object()) continue;
      const std::string from = l.value("from", std::string());
      if (from != "previous" && from != "source") out.push_back(lw + ".from: expected previous or source");
      if (const auto attrs = l.find("attributes"); attrs != l.end() && attrs->is_object()) {
        for (const auto& [name, value] : attrs->items()) {
          if (!value.is_number()) out.push_back(lw + ".attributes." + name + ": expected a number");
        }
      }
      const auto t = l.find("target");
      if (t == l.end() || !t->is_object() || !t->contains("kind") || !(*t)["kind"].is_string() ||
          !t->contains("value") || !(*t)["value"].is_number()) {
        out.push_back(lw + ".target: expected {\"kind\": string, \"value\": number}");
      } else {
        const std::string kind = (*t)["kind"];
        if (kind != "ratio" && kind != "triangles" && kind != "max_error" && kind != "screen_size") {
          out.push_back(lw + ".target.kind: expected ratio, triangles, max_error or screen_size");
        }
      }
    }
  }
  return out;
}

Json without_timings(Json report) {
  strip_seconds(report);
  return report;
}

Json merge_reports(const std::vector<Json>& reports) {
  if (reports.empty()) throw std::invalid_argument("no reports to merge");
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const std::vector<std::string> problems = check_report(reports[i]);
    if (!problems.empty()) {
      throw std::invalid_argument(
          "report " + std::to_string(i + 1) + " is malformed: " + problems.front() +
          (problems.size() > 1 ? " (and " + std::to_string(problems.size() - 1) + " more)" : ""));
    }
  }
  const Json& first = reports.front();
  for (std::size_t i = 1; i < reports.size(); ++i) {
    for (const char* key : {"lodforge_version", "effective_config"}) {
      if (reports[i][key] != first[key]) {
        throw std::invalid_argument(std::string("report ") + std::to_string(i + 1) + " has a different " + key +
                                    " than report 1; shards of one run share both");
      }
    }
  }
  std::vector<Json> assets;
  double seconds = 0;
  for (const Json& r : reports) {
    for (const Json& a : r["assets"]) assets.push_back(a);
    seconds = std::max(seconds, r["summary"]["seconds"].get<double>());
  }
  std::sort(assets.begin(), assets.end(),
            [](const Json& a, const Json& b) { return a["path"].get<std::string>() < b["path"].get<std::string>(); });
  for (std::size_t i = 1; i < assets.size(); ++i) {
    if (assets[i]["path"] == assets[i - 1]["path"]) {
      throw std::invalid_argument("asset " + assets[i]["path"].get<std::string>() +
                                  " is in two reports; were the same shard's reports given twice?");
    }
  }
  Json merged = Json::object();
  merged["lodforge_version"] = first["lodforge_version"];
  merged["config_file"] = first["config_file"];
  merged["effective_config"] = first["effective_config"];
  merged["jobs"] = first["jobs"];
  // The folders, where every shard names the same (shards on different machines may not): else unknown.
  for (const char* key : {"input_dir", "output_dir"}) {
    const auto same = [&](const Json& r) { return r.contains(key) && first.contains(key) && r[key] == first[key]; };
    merged[key] = std::all_of(reports.begin(), reports.end(), same) ? first[key] : Json(nullptr);
  }
  merged["shard"] = nullptr;
  Json list = Json::array();
  for (Json& a : assets) list.push_back(std::move(a));
  merged["summary"] = report_summary(list, seconds);
  merged["assets"] = std::move(list);
  return merged;
}

namespace {

// "assets" as path -> record, skipping entries that are not objects with a string path.
std::map<std::string, const Json*> assets_by_path(const Json& report) {
  std::map<std::string, const Json*> out;
  if (!report.is_object()) return out;
  const auto it = report.find("assets");
  if (it == report.end() || !it->is_array()) return out;
  for (const Json& a : *it) {
    if (!a.is_object()) continue;
    const auto p = a.find("path");
    if (p != a.end() && p->is_string()) out.emplace(p->get<std::string>(), &a);
  }
  return out;
}

std::string string_field(const Json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

Json number_field(const Json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number() && std::isfinite(it->get<double>()) ? *it : Json(nullptr);
}

// More than 5% of the previous value; any change from zero; appearing or vanishing counts.
bool moved(const Json& before, const Json& after) {
  if (before.is_null() || after.is_null()) return before.is_null() != after.is_null();
  const double a = before.get<double>(), b = after.get<double>();
  return std::abs(b - a) > 0.05 * std::abs(a) && a != b;
}

const Json& lods_of(const Json& asset) {
  static const Json kEmpty = Json::array();
  const auto it = asset.find("lods");
  return it != asset.end() && it->is_array() ? *it : kEmpty;
}

}  // namespace

Json diff_reports(const Json& previous, const Json& current) {
  const auto before = assets_by_path(previous), after = assets_by_path(current);
  Json added = Json::array(), removed = Json::array(), rebuilt = Json::array(), status = Json::array(),
       lods = Json::array();
  for (const auto& [path, a] : before) {
    if (!after.count(path)) removed.push_back(path);
  }
  for (const auto& [path, b] : after) {
    const auto it = before.find(path);
    if (it == before.end()) {
      added.push_back(path);
      continue;
    }
    const Json& a = *it->second;
    const std::string sa = string_field(a, "status"), sb = string_field(*b, "status");
    if (sa != sb) status.push_back({{"path", path}, {"from", sa}, {"to", sb}});
    const auto hit = b->find("cache_hit");
    if (sb == "ok" && !(hit != b->end() && hit->is_boolean() && hit->get<bool>())) rebuilt.push_back(path);
    const Json &la = lods_of(a), &lb = lods_of(*b);
    for (std::size_t k = 0; k < std::min(la.size(), lb.size()); ++k) {
      if (!la[k].is_object() || !lb[k].is_object()) continue;
      const Json ta = number_field(la[k], "triangles"), tb = number_field(lb[k], "triangles");
      const Json ha = number_field(la[k], "hausdorff_rel"), hb = number_field(lb[k], "hausdorff_rel");
      Json which = Json::array();
      if (moved(ta, tb)) which.push_back("triangles");
      if (moved(ha, hb)) which.push_back("hausdorff_rel");
      if (which.empty()) continue;
      const Json level = number_field(lb[k], "level");
      lods.push_back({{"path", path},
                      {"level", level.is_null() ? Json(k + 1) : level},
                      {"triangles", {ta, tb}},
                      {"hausdorff_rel", {ha, hb}},
                      {"moved", std::move(which)}});
    }
    if (la.size() != lb.size() && sa == "ok" && sb == "ok") {
      lods.push_back({{"path", path},
                      {"level", nullptr},
                      {"triangles", {nullptr, nullptr}},
                      {"hausdorff_rel", {nullptr, nullptr}},
                      {"lod_count", {la.size(), lb.size()}},
                      {"moved", {"lod_count"}}});
    }
  }
  return {{"previous_assets", before.size()}, {"added", std::move(added)},      {"removed", std::move(removed)},
          {"rebuilt", std::move(rebuilt)},   {"status_changed", std::move(status)}, {"lods_moved", std::move(lods)}};
}

namespace {

std::string number_text(const Json& v, bool percent) {
  if (!v.is_number()) return "-";
  char buf[64];
  if (percent) {
    std::snprintf(buf, sizeof buf, "%.4f%%", v.get<double>() * 100.0);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f", v.get<double>());
  }
  return buf;
}

const Json& list_of(const Json& changes, const char* key) {
  static const Json kEmpty = Json::array();
  if (!changes.is_object()) return kEmpty;
  const auto it = changes.find(key);
  return it != changes.end() && it->is_array() ? *it : kEmpty;
}

}  // namespace

std::string changes_text(const Json& changes, std::size_t max_lines) {
  const Json &added = list_of(changes, "added"), &removed = list_of(changes, "removed"),
             &rebuilt = list_of(changes, "rebuilt"), &status = list_of(changes, "status_changed"),
             &lods = list_of(changes, "lods_moved");
  std::string out = std::to_string(added.size()) + " added, " + std::to_string(removed.size()) + " removed, " +
                    std::to_string(rebuilt.size()) + " rebuilt, " + std::to_string(status.size()) +
                    " changed status, " + std::to_string(lods.size()) + " LODs moved by more than 5%\n";
  const auto section = [&](const Json& list, const char* title, auto line) {
    if (list.empty()) return;
    out += std::string(title) + ":\n";
    std::size_t n = 0;
    for (const Json& e : list) {
      if (max_lines != 0 && n == max_lines) {
        out += "  ... and " + std::to_string(list.size() - n) + " more\n";
        break;
      }
      out += "  " + line(e) + "\n";
      ++n;
    }
  };
  const auto path = [](const Json& e) { return e.is_string() ? e.get<std::string>() : std::string("?"); };
  section(added, "added", path);
  section(removed, "removed", path);
  section(rebuilt, "rebuilt", path);
  section(status, "status changed", [](const Json& e) {
    return string_field(e, "path") + ": " + string_field(e, "from") + " -> " + string_field(e, "to");
  });
  section(lods, "LODs moved", [](const Json& e) {
    if (!e.is_object()) return std::string("?");
    const std::string path = string_field(e, "path");
    if (const auto c = e.find("lod_count"); c != e.end() && c->is_array() && c->size() == 2) {
      return path + ": " + number_text((*c)[0], false) + " -> " + number_text((*c)[1], false) + " LODs";
    }
    const Json level = number_field(e, "level");
    std::string s = path + " LOD" + number_text(level, false) + ":";
    const auto pair = [&](const char* key, bool percent, const char* label) {
      const auto it = e.find(key);
      if (it == e.end() || !it->is_array() || it->size() != 2) return;
      s += std::string(" ") + label + " " + number_text((*it)[0], percent) + " -> " + number_text((*it)[1], percent);
    };
    pair("triangles", false, "triangles");
    pair("hausdorff_rel", true, "Hausdorff");
    return s;
  });
  return out;
}

void write_report(const Json& report, const std::filesystem::path& json_path, const std::filesystem::path& html_path) {
  io::write_file_atomic(json_path, report.dump(1) + "\n");
  io::write_file_atomic(html_path, render_report_html(report));
}

}  // namespace lodforge::batch
