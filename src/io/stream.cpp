// Streaming readers (stream.hpp): OBJ here, binary PLY in ply.cpp (it shares the PLY header parser).
#include "lodforge/io/stream.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <map>

#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "stream_internal.hpp"
#include "text_parse.hpp"

namespace lodforge::io {
namespace {

using parse::ErrorContext;


void stream_obj(const std::filesystem::path& path, const StreamSinks& sinks, StreamResult& result) {
  FileReader reader(path);
  ErrorContext ctx{path};
  std::uint64_t vertices = 0;
  std::vector<std::uint32_t> face;
  std::map<std::string, std::size_t> ignored;
  std::string material;     // the current `usemtl` name
  bool any_face = false;    // a face was read: its material is result.material
  std::string_view line;
  while (reader.next_line(line)) {
    ++ctx.line;
    std::string_view rest = line;
    const std::string_view keyword = parse::next_token(rest);
    if (keyword.empty() || keyword[0] == '#') continue;
    if (keyword == "v") {
      std::array<float, 7> x{};
      const int n = parse::parse_reals(ctx, rest, x.data(), 7, "a 'v' statement");
      if (n < 3 || n == 5) ctx.fail("'v' statement has " + std::to_string(n) + " values (x y z or x y z w expected)");
      if (n >= 6) refuse_out_of_core(ctx, "vertex colours");
      const Vec3f p{{x[0], x[1], x[2]}};
      parse::check_finite_position(ctx, p, vertices);
      if (vertices >= parse::kMaxIndexableElements) ctx.fail("too many vertices for 32-bit indices");
      sinks.vertex(p);
      ++vertices;
    } else if (keyword == "f") {
      face.clear();
      for (std::string_view token = parse::next_token(rest); !token.empty(); token = parse::next_token(rest)) {
        std::int64_t index = 0;
        const char* p = parse::parse_int_prefix(token.data(), token.data() + token.size(), index);
        // "v/vt/vn": the texture and normal indices refer to 'vt'/'vn' lines, refused where they appear.
        if (!p || (p != token.data() + token.size() && *p != '/')) ctx.fail("malformed face corner " + parse::quote(token));
        if (index == 0) ctx.fail("face uses vertex index 0 (OBJ indices start at 1)");
        const std::int64_t resolved = index < 0 ? static_cast<std::int64_t>(vertices) + index : index - 1;
        if (resolved < 0 || static_cast<std::uint64_t>(resolved) >= vertices) {
          ctx.fail("face uses vertex " + std::to_string(index) + ", which is not defined above it (" +
                   std::to_string(vertices) + " are; read out of core, a face may use only earlier vertices)");
        }
        face.push_back(static_cast<std::uint32_t>(resolved));
      }
      if (face.size() < 3) ctx.fail("face has " + std::to_string(face.size()) + " vertices (at least 3 needed)");
      if (!any_face) {
        result.material = material;
        any_face = true;
      } else if (material != result.material) {
        refuse_out_of_core(ctx, "faces in two materials (" + parse::quote(result.material) + ", " + parse::quote(material) + ")");
      }
      sinks.face(face);
    } else if (keyword == "vt") {
      refuse_out_of_core(ctx, "texture coordinates ('vt')");
    } else if (keyword == "vn") {
      refuse_out_of_core(ctx, "normals ('vn')");
    } else if (keyword == "usemtl") {
      material = std::string(parse::trim(rest));
    } else if (keyword == "mtllib") {
      result.mtllibs.emplace_back(parse::trim(rest));
    } else if (keyword == "s") {
      // Smoothing groups: shading only, which a positions-only mesh does not carry.
    } else if (keyword == "g" || keyword == "o" ||
               std::all_of(keyword.begin(), keyword.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; })) {
      ++ignored[std::string(keyword)];
    } else {
      ctx.fail("not an OBJ statement: " + parse::quote(line));
    }
  }
  for (const auto& [keyword, count] : ignored) {
    result.warnings.push_back("skipped " + std::to_string(count) + " '" + keyword + "' statement(s)" +
                       (keyword == "g" || keyword == "o" ? " (groups are not kept when reading out of core)" : ""));
  }
}

StreamCounts obj_counts(const std::filesystem::path& path) {
  FileReader reader(path);
  StreamCounts c;
  std::string_view line;
  while (reader.next_line(line)) {
    std::string_view rest = line;
    const std::string_view keyword = parse::next_token(rest);
    if (keyword == "v") {
      ++c.vertices;
    } else if (keyword == "f") {
      std::uint64_t corners = 0;
      while (!parse::next_token(rest).empty()) ++corners;
      if (corners >= 3) c.triangles += corners - 2;
    }
  }
  return c;
}

}  // namespace

void refuse_out_of_core(const parse::ErrorContext& ctx, const std::string& what) {
  ctx.fail("the file has " + what + ", and reading it out of core keeps positions and faces only (raise "
           "--memory-limit so that it loads whole)");
}

FileReader::FileReader(const std::filesystem::path& path) : path_(path) {
  file_ = std::fopen(path.c_str(), "rb");
  if (file_ == nullptr) throw IoError(path, std::string("cannot open: ") + std::strerror(errno));
  std::error_code ec;
  size_ = std::filesystem::file_size(path, ec);
  if (ec) {
    std::fclose(file_);
    throw IoError(path, "cannot read its size: " + ec.message());
  }
  buffer_.resize(kStreamBufferBytes);
}

FileReader::~FileReader() {
  if (file_ != nullptr) std::fclose(file_);
}

bool FileReader::fill(std::size_t at_least) {
  if (end_ - begin_ >= at_least) return true;
  // Keep what is unread at the front, then read behind it.
  std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
  consumed_ += begin_;
  end_ -= begin_;
  begin_ = 0;
  if (buffer_.size() < at_least) buffer_.resize(std::max(at_least, 2 * buffer_.size()));
  while (end_ < at_least) {
    const std::size_t got = std::fread(buffer_.data() + end_, 1, buffer_.size() - end_, file_);
    if (got == 0) {
      if (std::ferror(file_)) throw IoError(path_, std::string("read failed: ") + std::strerror(errno));
      return false;
    }
    end_ += got;
  }
  return true;
}

const char* FileReader::take(std::size_t n) {
  if (!fill(n)) return nullptr;
  const char* p = buffer_.data() + begin_;
  begin_ += n;
  return p;
}

bool FileReader::next_line(std::string_view& line) {
  for (;;) {
    const char* start = buffer_.data() + begin_;
    const void* nl = std::memchr(start, '\n', end_ - begin_);
    if (nl != nullptr) {
      const std::size_t n = static_cast<const char*>(nl) - start;
      line = std::string_view(start, n);
      begin_ += n + 1;
      return true;
    }
    const std::size_t have = end_ - begin_;
    if (!fill(have + 1)) {  // the end of the file: the last line has no '\n'
      if (end_ == begin_) return false;
      line = std::string_view(buffer_.data() + begin_, end_ - begin_);
      begin_ = end_;
      return true;
    }
  }
}

bool streamable(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  return ext == ".ply" || ext == ".obj";
}

StreamCounts stream_counts(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".ply") return ply_counts(path);
  if (ext == ".obj") return obj_counts(path);
  throw IoError(path, "cannot be read out of core (binary PLY and OBJ only)");
}

StreamResult stream_mesh(const std::filesystem::path& path, const StreamSinks& sinks) {
  StreamResult result;
  const std::string ext = lower_extension(path);
  if (ext == ".ply") {
    stream_ply(path, sinks);
  } else if (ext == ".obj") {
    stream_obj(path, sinks, result);
  } else {
    throw IoError(path, "cannot be read out of core (binary PLY and OBJ only)");
  }
  return result;
}

}  // namespace lodforge::io
