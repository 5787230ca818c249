// libFuzzer harness: load_config on any bytes (batch/config.hpp). A rejected config must be a ConfigError; an
// accepted one must give an effective config that parse_config accepts back as the same config (documented
// for the report, which records it), and every LOD of every class must resolve to SimplifyOptions.
#include <nlohmann/json.hpp>

#include "fuzz_support.hpp"
#include "lodforge/batch/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace batch = lodforge::batch;
  namespace fuzz = lodforge::fuzz;
  const std::filesystem::path path = fuzz::write_input("config.json", fuzz::as_text(data, size));
  batch::BatchConfig config;
  try {
    config = batch::load_config(path);
  } catch (const batch::ConfigError&) {
    return 0;  // the documented rejection
  }

  const nlohmann::json effective = batch::effective_config_json(config);
  (void)effective.dump(2);  // as the report writes it
  try {
    const batch::BatchConfig again = batch::parse_config(effective, "effective config");
    if (batch::effective_config_json(again) != effective) fuzz::fail("the effective config changes when parsed back");
  } catch (const batch::ConfigError& e) {
    fuzz::fail(std::string("parse_config rejects the effective config: ") + e.what());
  }

  const batch::LodInput input{.source_triangles = 1000, .source_diagonal = 2.0, .accumulated_error_abs = 0.01};
  for (const batch::AssetClass& cls : config.classes) {
    (void)batch::effective_class_json(config, cls);
    for (const batch::LodSpec& lod : cls.lods) (void)batch::simplify_options_for(lod, input);
  }
  for (const char* asset : {"props/chair.obj", "characters/hero/hero.glb", "rock.ply", ""}) {
    if (!batch::match_class(config, asset)) (void)batch::unmatched_reason(config, asset);
  }
  return 0;
}
