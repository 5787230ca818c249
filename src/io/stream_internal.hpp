// Private to the io part: a buffered sequential reader for the streaming readers (stream.cpp, ply.cpp).
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/io/stream.hpp"

namespace lodforge::io {

// Reads a file front to back through a fixed buffer: bytes by count (binary bodies) or lines (text).
class FileReader {
 public:
  explicit FileReader(const std::filesystem::path& path);
  ~FileReader();
  FileReader(const FileReader&) = delete;
  FileReader& operator=(const FileReader&) = delete;

  std::uint64_t size() const { return size_; }
  std::uint64_t consumed() const { return consumed_ + static_cast<std::uint64_t>(begin_); }
  std::uint64_t remaining() const { return size_ - consumed(); }
  // The next n bytes (valid until the next call), or nullptr where the file ends first.
  const char* take(std::size_t n);
  // The next line without its '\n' (valid until the next call); false at the end of the file.
  bool next_line(std::string_view& line);

 private:
  bool fill(std::size_t at_least);

  const std::filesystem::path& path_;
  std::FILE* file_ = nullptr;
  std::uint64_t size_ = 0;
  std::uint64_t consumed_ = 0;  // bytes before buffer_[0]
  std::vector<char> buffer_;
  std::size_t begin_ = 0, end_ = 0;
};

namespace parse {
struct ErrorContext;
}

// Fails naming `what` the file has that reading it out of core would drop.
[[noreturn]] void refuse_out_of_core(const parse::ErrorContext& ctx, const std::string& what);

// The binary PLY body, streamed (ply.cpp).
void stream_ply(const std::filesystem::path& path, const StreamSinks& sinks);
StreamCounts ply_counts(const std::filesystem::path& path);

}  // namespace lodforge::io
