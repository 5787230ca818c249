#include "lodforge/batch/lods_manifest.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <system_error>

#include "lodforge/batch/config.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/io/file.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

double number_or(const Json& object, const char* key, double fallback) {
  if (!object.is_object()) return fallback;
  const auto it = object.find(key);
  return it != object.end() && it->is_number() ? it->get<double>() : fallback;
}

// JSON holds no infinity: a distance without an end is null.
Json distance(double d) {
  return std::isfinite(d) ? Json(d) : Json(nullptr);
}

// Whether a LOD record shows the meshes of the level before; records cached before the flag existed say so only
// in their budget reasons.
bool shows_previous(const Json& lod) {
  if (const auto it = lod.find("shows_previous"); it != lod.end() && it->is_boolean()) return it->get<bool>();
  if (const auto b = lod.find("budget"); b != lod.end() && b->is_object() && b->contains("reasons")) {
    for (const Json& r : (*b)["reasons"]) {
      if (r.is_string() && r.get<std::string>().find(": shows its meshes") != std::string::npos) return true;
    }
  }
  return false;
}

Json entry_of(const Json& record, const LodSwitch& sw) {
  const std::string path = record["path"].get<std::string>();
  const fs::path rel(path);
  std::set<std::string> outputs;
  for (const Json& o : record["outputs"]) outputs.insert(o.get<std::string>());
  auto output = [&](const fs::path& p) {
    return outputs.count(p.generic_string()) ? Json(p.generic_string()) : Json();
  };
  const Json msft = output(rel);  // an MSFT_lod glTF keeps the source's name
  auto level_file = [&](std::size_t k) { return output(rel.parent_path() / lod_file_name(rel.filename(), k)); };

  const Json& input = record["input"];
  const double diagonal = number_or(input, "diagonal", 0), radius = diagonal / 2;
  const Json& records = record["lods"];
  const std::size_t n = records.size();

  // Switch-in coverage per level (level 0: the whole screen), as report.json and MSFT_screencoverage have it.
  std::vector<double> coverage{1.0};
  for (const Json& l : records) {
    const double measured = coverage_for_error(number_or(l, "hausdorff_rel", 0), sw.error_px, sw.screen_height_px);
    coverage.push_back(number_or(l, "screen_coverage", std::min(measured, coverage.back())));
  }
  std::vector<double> begin(n + 1);
  for (std::size_t k = 1; k <= n; ++k) begin[k] = distance_for_coverage(radius, coverage[k], sw.fov_y_deg);

  Json lods = Json::array();
  std::vector<Json> files(n + 1);
  for (std::size_t k = 0; k <= n; ++k) {
    const Json* l = k == 0 ? nullptr : &records[k - 1];
    const bool reuses = l && shows_previous(*l);
    // A level that shows the one before has no file of its own: it points where that level points.
    Json file = reuses ? files[k - 1] : level_file(k);
    if (file.is_null() && !msft.is_null()) file = msft;
    files[k] = file;
    const double hausdorff_rel = l ? number_or(*l, "hausdorff_rel", 0) : 0.0;
    Json e = {{"level", k},
              {"file", file},
              {"triangles", l ? (*l)["triangles"] : input["triangles"]},
              {"reuses_previous", reuses},
              {"hausdorff", hausdorff_rel * diagonal},
              {"hausdorff_percent", hausdorff_rel * 100},
              {"screen_coverage", coverage[k]},
              {"unreal_screen_size", coverage[k]},
              {"unity_screen_relative_transition_height", k < n ? coverage[k + 1] : 0.0},
              {"godot_visibility_range_begin", begin[k]},
              {"godot_visibility_range_end", k < n ? distance(begin[k + 1]) : Json(0.0)}};
    if (!msft.is_null()) {
      e["msft_lod"] = {{"file", msft},
                       {"index", k == 0 ? Json(nullptr) : Json(k - 1)},
                       {"node_suffix", k == 0 ? "" : "_LOD" + std::to_string(k)}};
    }
    lods.push_back(std::move(e));
  }
  return {{"path", path},     {"class", record["class"]},        {"diagonal", diagonal},
          {"radius", radius}, {"unity_lodgroup_size", diagonal}, {"lods", std::move(lods)}};
}

}  // namespace

Json lods_manifest(const Json& report, const Json& previous, bool keep_unlisted) {
  LodSwitch sw;
  Json defaults = Json::object();
  if (report.contains("effective_config") && report["effective_config"].contains("defaults")) {
    defaults = report["effective_config"]["defaults"];
  }
  if (const auto it = defaults.find("lod_switch"); it != defaults.end() && it->is_object()) {
    sw.screen_height_px = number_or(*it, "screen_height_px", sw.screen_height_px);
    sw.error_px = number_or(*it, "error_px", sw.error_px);
    sw.fov_y_deg = number_or(*it, "fov_y_deg", sw.fov_y_deg);
  }

  std::map<std::string, Json> old;
  if (previous.is_object() && previous.contains("assets") && previous["assets"].is_array()) {
    for (const Json& e : previous["assets"]) {
      if (e.is_object() && e.contains("path") && e["path"].is_string()) old[e["path"].get<std::string>()] = e;
    }
  }
  std::map<std::string, Json> entries;
  std::set<std::string> listed;
  for (const Json& a : report["assets"]) {
    const std::string path = a["path"].get<std::string>();
    const std::string status = a["status"].get<std::string>();
    if (status == "skipped") continue;  // its outputs, if any, are stale
    listed.insert(path);
    if (status == "ok") {
      entries[path] = entry_of(a, sw);
    } else if (const auto it = old.find(path); it != old.end()) {
      entries[path] = it->second;  // failed or not started: its last good outputs stay, and so does their entry
    }
  }
  if (keep_unlisted) {
    for (auto& [path, e] : old) {
      if (!listed.count(path)) entries.emplace(path, std::move(e));
    }
  }
  Json assets = Json::array();
  for (auto& [path, e] : entries) assets.push_back(std::move(e));
  return {{"format", "lodforge.lods"},
          {"version", kLodsManifestVersion},
          {"gltf_lods", defaults.value("gltf_lods", std::string("msft_lod"))},
          {"lod_switch",
           {{"screen_height_px", sw.screen_height_px}, {"error_px", sw.error_px}, {"fov_y_deg", sw.fov_y_deg}}},
          {"assets", std::move(assets)}};
}

Json read_lods_manifest(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return nullptr;
  try {
    Json j = Json::parse(io::read_file(path));
    if (j.is_object() && j.value("format", std::string()) == "lodforge.lods") return j;
  } catch (const std::exception&) {
    // Not a manifest: the run writes a fresh one.
  }
  return nullptr;
}

void write_lods_manifest(const Json& manifest, const fs::path& path) {
  io::write_file_atomic(path, manifest.dump(1) + "\n");
}

}  // namespace lodforge::batch
