// File helpers: whole-file reads with clear errors, atomic writes (temporary file in the same folder, fsync,
// rename), and a check that a relative URI stays inside a folder (no path traversal).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace lodforge::io {

// Reads a whole file; throws IoError("<path>: cannot open ..."), also for directories.
std::string read_file(const std::filesystem::path& path);

// Throws IoError when `path` is an existing folder: an output must be a file. Writers of several files (.gltf
// and its .bin) call it before writing any, so none is left behind.
void check_output_path(const std::filesystem::path& path);

// Whether write_file_atomic waits for the data to reach the disk (fsync) before the rename. `none` is for files
// the next run draws again (the report's pictures): a crash may then lose the file's contents, never leave a
// half-written file under its name.
enum class Durability { synced, none };

// Writes `bytes` to `path` atomically: the data goes to "<path>.tmp-<pid>-<n>" in the same folder and is
// renamed over `path` only when complete. On failure nothing is left behind and IoError is thrown.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes,
                       Durability durability = Durability::synced);

// Resolves `uri` (a relative reference, percent-decoded) against `folder`. Throws IoError naming `asset` when
// the URI is absolute, has a scheme other than data:, or escapes `folder` through "..".
std::filesystem::path resolve_inside(const std::filesystem::path& asset, const std::filesystem::path& folder,
                                     std::string_view uri);

std::string percent_decode(std::string_view s);

// The path's extension ("" or ".xyz") in lower case, as the readers and the batch compare extensions.
std::string lower_extension(const std::filesystem::path& path);

}  // namespace lodforge::io
