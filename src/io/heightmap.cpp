// Height-map reading: 16-bit grey PNG through stb_image, raw little-endian .r16, sidecar JSON.
#include "lodforge/io/heightmap.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/picture.hpp"

#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#define STBI_NO_STDIO
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#endif
#include <stb_image.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

namespace lodforge::io {

namespace {

// Beyond this many samples a map is refused before anything is allocated (a 64k x 64k map is 8 GiB of
// samples, more than the rest of the pipeline could hold as meshes anyway).
constexpr std::size_t kMaxSamples = std::size_t{1} << 32;

double positive_number(const nlohmann::json& j, const char* key, const std::filesystem::path& sidecar) {
  if (!j.is_number() || !std::isfinite(j.get<double>()) || j.get<double>() <= 0.0) {
    throw IoError(sidecar, std::string{"\""} + key + "\" must be a positive number");
  }
  return j.get<double>();
}

std::size_t size_value(const nlohmann::json& j, const char* key, const std::filesystem::path& sidecar) {
  if (!j.is_number_unsigned() || j.get<std::uint64_t>() < 2 || j.get<std::uint64_t>() > (1u << 20)) {
    throw IoError(sidecar, std::string{"\""} + key + "\" must be a whole number from 2 to 1048576");
  }
  return static_cast<std::size_t>(j.get<std::uint64_t>());
}

// The sidecar's keys over `layout`.
void apply_sidecar(const std::filesystem::path& sidecar, HeightMapLayout& layout) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(read_file(sidecar));
  } catch (const nlohmann::json::exception& e) {
    throw IoError(sidecar, std::string{"not valid JSON: "} + e.what());
  }
  if (!j.is_object()) throw IoError(sidecar, "a height map's sidecar must be a JSON object");
  for (const auto& [key, value] : j.items()) {
    if (key == "width") {
      layout.width = size_value(value, "width", sidecar);
    } else if (key == "height") {
      layout.height = size_value(value, "height", sidecar);
    } else if (key == "spacing") {
      if (value.is_array() && value.size() == 2) {
        layout.spacing_x = positive_number(value[0], "spacing", sidecar);
        layout.spacing_z = positive_number(value[1], "spacing", sidecar);
      } else {
        layout.spacing_x = layout.spacing_z = positive_number(value, "spacing", sidecar);
      }
    } else if (key == "spacing_x") {
      layout.spacing_x = positive_number(value, "spacing_x", sidecar);
    } else if (key == "spacing_z") {
      layout.spacing_z = positive_number(value, "spacing_z", sidecar);
    } else if (key == "height_scale") {
      if (!value.is_number() || !std::isfinite(value.get<double>()) || value.get<double>() == 0.0) {
        throw IoError(sidecar, "\"height_scale\" must be a non-zero number");
      }
      layout.height_scale = value.get<double>();
    } else if (key == "height_offset") {
      if (!value.is_number() || !std::isfinite(value.get<double>())) {
        throw IoError(sidecar, "\"height_offset\" must be a number");
      }
      layout.height_offset = value.get<double>();
    } else if (key == "nodata") {
      if (value.is_null()) {
        layout.nodata.reset();
      } else if (value.is_number_unsigned() && value.get<std::uint64_t>() <= 65535) {
        layout.nodata = static_cast<std::uint16_t>(value.get<std::uint64_t>());
      } else {
        throw IoError(sidecar, "\"nodata\" must be a sample value from 0 to 65535, or null");
      }
    } else {
      throw IoError(sidecar, "unknown key \"" + key +
                                 "\" (known: width, height, spacing, spacing_x, spacing_z, height_scale, "
                                 "height_offset, nodata)");
    }
  }
}

void read_png(const std::filesystem::path& path, const std::string& bytes, HeightMap& map) {
  const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
  const int length = static_cast<int>(std::min<std::size_t>(bytes.size(), std::numeric_limits<int>::max()));
  int w = 0, h = 0, channels = 0;
  if (!stbi_info_from_memory(data, length, &w, &h, &channels)) {
    throw IoError(path, std::string{"not a readable PNG ("} + stbi_failure_reason() + ")");
  }
  if (channels > 2) {
    throw IoError(path,
                  "a height map must be a grey PNG (this one has " + std::to_string(channels) + " channels: colour)");
  }
  if (w < 2 || h < 2) throw IoError(path, "a height map needs at least 2 x 2 samples");
  if (static_cast<std::size_t>(w) * static_cast<std::size_t>(h) > kMaxSamples) {
    throw IoError(path, "the height map is too large");
  }
  const bool sixteen = stbi_is_16_bit_from_memory(data, length) != 0;
  if (channels == 2) map.warnings.push_back("the PNG's alpha channel is ignored");
  map.width = static_cast<std::size_t>(w);
  map.height = static_cast<std::size_t>(h);
  map.samples.resize(map.width * map.height);
  int got = 0;
  if (sixteen) {
    stbi_us* pixels = stbi_load_16_from_memory(data, length, &w, &h, &got, 1);
    if (!pixels) throw IoError(path, std::string{"cannot decode the PNG ("} + stbi_failure_reason() + ")");
    std::copy(pixels, pixels + map.samples.size(), map.samples.begin());
    stbi_image_free(pixels);
  } else {
    map.warnings.push_back("an 8-bit PNG: samples are 0..255");
    stbi_uc* pixels = stbi_load_from_memory(data, length, &w, &h, &got, 1);
    if (!pixels) throw IoError(path, std::string{"cannot decode the PNG ("} + stbi_failure_reason() + ")");
    std::copy(pixels, pixels + map.samples.size(), map.samples.begin());
    stbi_image_free(pixels);
  }
}

// The last "<W>x<H>" in the file's stem, or {0, 0}.
std::pair<std::size_t, std::size_t> size_from_name(const std::filesystem::path& path) {
  static const std::regex pattern{R"((\d{1,7})[xX](\d{1,7}))"};
  const std::string stem = path.stem().string();
  std::pair<std::size_t, std::size_t> found{0, 0};
  for (auto it = std::sregex_iterator(stem.begin(), stem.end(), pattern); it != std::sregex_iterator(); ++it) {
    found = {std::stoull((*it)[1].str()), std::stoull((*it)[2].str())};
  }
  return found;
}

void read_raw(const std::filesystem::path& path, const std::string& bytes, HeightMap& map) {
  if (bytes.size() % 2 != 0) throw IoError(path, "a .r16 file holds 16-bit samples: its size must be even");
  const std::size_t count = bytes.size() / 2;
  std::size_t w = map.layout.width, h = map.layout.height;
  std::string from = "its layout";
  if (w == 0 && h == 0) {
    std::tie(w, h) = size_from_name(path);
    from = "its file name";
  }
  if (w == 0 && h == 0) {
    const auto side = static_cast<std::size_t>(std::llround(std::sqrt(static_cast<double>(count))));
    if (side * side != count) {
      throw IoError(path, "a raw height map needs its size: give width and height in a sidecar \"" +
                              path.filename().string() +
                              ".json\", in the config, or as \"<W>x<H>\" in the file name (" + std::to_string(count) +
                              " samples are not a square)");
    }
    w = h = side;
    from = "its square size";
  }
  if (w == 0) w = count / h;
  if (h == 0) h = count / w;
  if (w < 2 || h < 2) throw IoError(path, "a height map needs at least 2 x 2 samples");
  if (w * h != count) {
    throw IoError(path, std::to_string(w) + " x " + std::to_string(h) + " samples (from " + from + ") need " +
                            std::to_string(2 * w * h) + " bytes; the file has " + std::to_string(bytes.size()));
  }
  map.width = w;
  map.height = h;
  map.samples.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    map.samples[i] = static_cast<std::uint16_t>(static_cast<std::uint8_t>(bytes[2 * i]) |
                                                (static_cast<std::uint8_t>(bytes[2 * i + 1]) << 8));
  }
}

}  // namespace

std::vector<std::string> HeightMapLayout::validate() const {
  std::vector<std::string> problems;
  const auto positive = [&](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0)) problems.push_back(std::string{name} + " must be a positive number");
  };
  positive(spacing_x, "spacing_x");
  positive(spacing_z, "spacing_z");
  if (!(std::isfinite(height_scale) && height_scale != 0.0)) problems.push_back("height_scale must be non-zero");
  if (!std::isfinite(height_offset)) problems.push_back("height_offset must be a number");
  if ((width != 0 && width < 2) || (height != 0 && height < 2)) problems.push_back("width and height are at least 2");
  return problems;
}

bool is_heightmap_path(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  return ext == ".png" || ext == ".r16";
}

HeightMap load_heightmap(const std::filesystem::path& path, const HeightMapLayout& defaults) {
  HeightMap map;
  map.layout = defaults;
  std::filesystem::path sidecar = path;
  sidecar += ".json";
  std::error_code ec;
  if (std::filesystem::is_regular_file(sidecar, ec)) apply_sidecar(sidecar, map.layout);
  if (const auto problems = map.layout.validate(); !problems.empty()) throw IoError(path, problems.front());
  const std::string ext = lower_extension(path);
  if (ext != ".png" && ext != ".r16") throw IoError(path, "not a height map (expected .png or .r16)");
  const std::string bytes = read_file(path);
  if (ext == ".png") {
    read_png(path, bytes, map);
    if ((map.layout.width != 0 && map.layout.width != map.width) ||
        (map.layout.height != 0 && map.layout.height != map.height)) {
      throw IoError(path, "the PNG is " + std::to_string(map.width) + " x " + std::to_string(map.height) +
                              ", its layout says " + std::to_string(map.layout.width) + " x " +
                              std::to_string(map.layout.height));
    }
  } else {
    read_raw(path, bytes, map);
  }
  map.layout.width = map.width;
  map.layout.height = map.height;
  if (map.layout.nodata) {
    const std::size_t holes =
        static_cast<std::size_t>(std::count(map.samples.begin(), map.samples.end(), *map.layout.nodata));
    if (holes == map.samples.size()) throw IoError(path, "every sample is the no-data value");
  }
  return map;
}

void save_heightmap_png(const HeightMap& map, const std::filesystem::path& path) {
  write_file_atomic(path, encode_png_grey16(static_cast<int>(map.width), static_cast<int>(map.height), map.samples));
}

}  // namespace lodforge::io
