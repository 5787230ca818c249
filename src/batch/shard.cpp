#include "lodforge/batch/shard.hpp"

#include <charconv>
#include <stdexcept>

namespace lodforge::batch {
namespace {

constexpr std::uint32_t kMaxShards = 1000000;

std::uint32_t parse_number(std::string_view s, const char* what, std::string_view text) {
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size() || v > kMaxShards) {
    throw std::invalid_argument("shard '" + std::string(text) + "': " + what + " must be a whole number up to " +
                                std::to_string(kMaxShards));
  }
  return static_cast<std::uint32_t>(v);
}

}  // namespace

Shard parse_shard(std::string_view text) {
  const auto slash = text.find('/');
  if (slash == std::string_view::npos) {
    throw std::invalid_argument("shard '" + std::string(text) + "': expected K/N, e.g. 0/4 (K is 0-based)");
  }
  Shard s;
  s.index = parse_number(text.substr(0, slash), "K", text);
  s.count = parse_number(text.substr(slash + 1), "N", text);
  if (s.count == 0) throw std::invalid_argument("shard '" + std::string(text) + "': N must be at least 1");
  if (s.index >= s.count) {
    throw std::invalid_argument("shard '" + std::string(text) + "': K must be in 0.." + std::to_string(s.count - 1) +
                                " (K is 0-based)");
  }
  return s;
}

std::string shard_name(const Shard& shard) {
  return std::to_string(shard.index) + "/" + std::to_string(shard.count);
}

std::uint64_t path_hash(std::string_view relative_path) {
  std::uint64_t h = 14695981039346656037ull;  // FNV-1a 64 offset basis and prime
  for (const char c : relative_path) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ull;
  }
  return h;
}

bool in_shard(const Shard& shard, std::string_view relative_path) {
  return path_hash(relative_path) % shard.count == shard.index;
}

}  // namespace lodforge::batch
