#include "lodforge/io/file.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <system_error>

#include "lodforge/io/asset.hpp"

namespace lodforge::io {

IoError::IoError(const std::filesystem::path& file, const std::string& problem)
    : std::runtime_error(file.string() + ": " + problem), file_(file), problem_(problem) {}

std::string read_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) throw IoError(path, "is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, std::string("cannot open: ") + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw IoError(path, "cannot determine the file size");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.seekg(0, std::ios::beg);
  if (size > 0 && !in.read(bytes.data(), size)) throw IoError(path, "read failed");
  return bytes;
}

void check_output_path(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw IoError(path, "is an existing folder; the output must be a file name");
  }
}

void write_file_atomic(const std::filesystem::path& path, std::string_view bytes, Durability durability) {
  check_output_path(path);
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path tmp =
      path.string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw IoError(path, std::string("cannot create a temporary file: ") + std::strerror(errno));
  bool ok = bytes.empty() || std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  ok = (std::fflush(f) == 0) && ok;
  if (durability == Durability::synced) ok = (::fsync(::fileno(f)) == 0) && ok;
  ok = (std::fclose(f) == 0) && ok;
  std::error_code ec;
  if (!ok) {
    std::filesystem::remove(tmp, ec);
    throw IoError(path, "write failed (disk full?)");
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    const std::string why = ec.message();  // before remove() reuses ec
    std::filesystem::remove(tmp, ec);
    throw IoError(path, "cannot rename the temporary file into place: " + why);
  }
}

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

std::string percent_decode(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%') {
      const int hi = i + 1 < s.size() ? hex(s[i + 1]) : -1;
      const int lo = i + 2 < s.size() ? hex(s[i + 2]) : -1;
      if (hi >= 0 && lo >= 0) {
        out.push_back(static_cast<char>(hi * 16 + lo));
        i += 2;
        continue;
      }
    }
    out.push_back(s[i]);
  }
  return out;
}

std::filesystem::path resolve_inside(const std::filesystem::path& asset, const std::filesystem::path& folder,
                                     std::string_view uri) {
  const std::string decoded = percent_decode(uri);
  if (decoded.empty()) throw IoError(asset, "empty URI");
  const auto colon = decoded.find(':');
  const auto slash = decoded.find('/');
  if (colon != std::string::npos && (slash == std::string::npos || colon < slash)) {
    throw IoError(asset, "URI '" + std::string(uri) + "' has a scheme; only relative paths and data: URIs are allowed");
  }
  const std::filesystem::path rel(decoded);
  if (rel.is_absolute() || decoded.front() == '/' || decoded.front() == '\\') {
    throw IoError(asset, "URI '" + std::string(uri) + "' is an absolute path; refusing to read outside the asset's folder");
  }
  const std::filesystem::path normal = rel.lexically_normal();
  if (normal.empty() || *normal.begin() == "..") {
    throw IoError(asset, "URI '" + std::string(uri) + "' points outside the asset's folder (path traversal refused)");
  }
  return folder / normal;
}

}  // namespace lodforge::io
