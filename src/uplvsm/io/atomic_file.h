// Whole-file I/O helpers: crash-safe writes (temp file in the same directory + fsync + rename, so a reader never
// sees a half-written checkpoint or video) and whole-file reads with errors that name the path.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm::io {

// Writes `size` bytes to `path` atomically; creates missing parent directories. Throws std::runtime_error.
void write_file_atomic(const std::string& path, const void* data, size_t size);

// The same for a file made of several buffers written back to back (no need to concatenate them in memory).
struct ByteSpan {
  const void* data = nullptr;
  size_t size = 0;
};
void write_file_atomic(const std::string& path, const std::vector<ByteSpan>& parts);

// A unique temporary path next to `path` (same directory, so rename() stays on one filesystem). Creates parent
// directories. Used by writers (e.g. libavformat) that must write through their own file handle.
std::string temp_path_for(const std::string& path);

// fsyncs `tmp_path`, renames it over `path` and fsyncs the directory; removes `tmp_path` and throws on failure.
void commit_temp_file(const std::string& tmp_path, const std::string& path);

// Reads the whole file. Throws std::runtime_error naming the path when it is missing or unreadable.
std::vector<uint8_t> read_file(const std::string& path);

}  // namespace uplvsm::io
