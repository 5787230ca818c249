#include "lodforge/batch/report.hpp"

#include <algorithm>
#include <cstdint>
#include <set>
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
                missed = 0;
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
    } else if (status == "failed") {
      ++failed;
    } else if (status == "not_started") {
      ++not_started;
    } else {
      ++skipped;
    }
    if (a.value("cache_hit", false)) ++hits;
  }
  return {{"assets", assets.size()}, {"succeeded", ok}, {"failed", failed},           {"skipped", skipped},
          {"cache_hits", hits},      {"lods", lods},    {"input_triangles", in_tris}, {"output_triangles", out_tris},
          {"seconds", seconds},      {"lods_missed", missed},   {"not_started", not_started}};
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
    }
    if (!a.contains("outputs") || !a["outputs"].is_array() ||
        !std::all_of(a["outputs"].begin(), a["outputs"].end(), [](const Json& o) { return o.is_string(); })) {
      out.push_back(where + ".outputs: expected an array of strings");
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
  merged["shard"] = nullptr;
  Json list = Json::array();
  for (Json& a : assets) list.push_back(std::move(a));
  merged["summary"] = report_summary(list, seconds);
  merged["assets"] = std::move(list);
  return merged;
}

void write_report(const Json& report, const std::filesystem::path& json_path, const std::filesystem::path& html_path) {
  io::write_file_atomic(json_path, report.dump(1) + "\n");
  io::write_file_atomic(html_path, render_report_html(report));
}

}  // namespace lodforge::batch
