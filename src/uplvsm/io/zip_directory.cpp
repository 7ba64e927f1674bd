#include "uplvsm/io/zip_directory.h"

#include <fstream>
#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::io {
namespace {

constexpr uint32_t kEndOfDirectory = 0x06054b50, kZip64Locator = 0x07064b50, kZip64End = 0x06064b50,
                   kDirectoryEntry = 0x02014b50;
// Deflate cannot expand data by more than ~1032:1 (258-byte matches coded in 2 bits); allow a little slack.
constexpr uint64_t kMaxDeflateRatio = 1040;

struct Bytes {
  std::string data;
  const std::string* path;
  uint64_t le(size_t at, int n) const {
    if (at > data.size() || size_t(n) > data.size() - at)
      throw std::runtime_error(fmt::format("{}: corrupt zip directory (field past its end)", *path));
    uint64_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | uint8_t(data[at + i]);
    return v;
  }
};

Bytes read_range(std::ifstream& in, const std::string& path, uint64_t offset, uint64_t size) {
  Bytes b{std::string(size, '\0'), &path};
  in.seekg(static_cast<std::streamoff>(offset));
  in.read(b.data.data(), static_cast<std::streamsize>(size));
  if (!in) throw std::runtime_error(fmt::format("{}: cannot read {} bytes at offset {}", path, size, offset));
  return b;
}

struct Directory {
  uint64_t entries = 0, size = 0, offset = 0;
};

// The end-of-central-directory record is in the last 22 + 65535 (comment) bytes; zip64 archives point from a locator
// just before it to a larger record holding 64-bit counts.
Directory find_directory(std::ifstream& in, const std::string& path, uint64_t file_size) {
  const uint64_t tail_size = std::min<uint64_t>(file_size, 22 + 65535 + 20);
  const Bytes tail = read_range(in, path, file_size - tail_size, tail_size);
  if (tail_size < 22)
    throw std::runtime_error(fmt::format("{}: {} bytes, too short for a zip archive", path, file_size));
  for (size_t at = tail_size - 22 + 1; at-- > 0;) {
    if (tail.le(at, 4) != kEndOfDirectory) continue;
    Directory d{tail.le(at + 10, 2), tail.le(at + 12, 4), tail.le(at + 16, 4)};
    if (d.entries == 0xffff || d.size == 0xffffffff || d.offset == 0xffffffff) {
      if (at < 20 || tail.le(at - 20, 4) != kZip64Locator)
        throw std::runtime_error(fmt::format("{}: corrupt zip archive (zip64 sizes without a zip64 locator)", path));
      const uint64_t record = tail.le(at - 20 + 8, 8);
      if (record > file_size || file_size - record < 56)
        throw std::runtime_error(fmt::format("{}: corrupt zip archive (zip64 record outside the file)", path));
      const Bytes z = read_range(in, path, record, 56);
      if (z.le(0, 4) != kZip64End) throw std::runtime_error(fmt::format("{}: corrupt zip64 end record", path));
      d = {z.le(32, 8), z.le(40, 8), z.le(48, 8)};
    }
    if (d.offset > file_size || d.size > file_size - d.offset)
      throw std::runtime_error(
          fmt::format("{}: truncated or corrupt zip archive (central directory of {} bytes at "
                      "offset {} is beyond the file size {})",
                      path, d.size, d.offset, file_size));
    return d;
  }
  throw std::runtime_error(
      fmt::format("{}: truncated or corrupt zip archive (no end-of-central-directory record)", path));
}

// Sizes and offset stored as 0xffffffff in an entry are in its zip64 extra field (id 1), in this order.
void apply_zip64_extra(const Bytes& cd, size_t extra_at, size_t extra_len, ZipEntry& e, const std::string& path) {
  uint64_t* fields[] = {&e.uncompressed_size, &e.compressed_size, &e.local_header_offset};
  for (size_t at = extra_at; at + 4 <= extra_at + extra_len;) {
    const uint64_t id = cd.le(at, 2), len = cd.le(at + 2, 2);
    if (id == 1) {
      size_t pos = at + 4;
      for (uint64_t* f : fields)
        if (*f == 0xffffffff) {
          if (pos + 8 > at + 4 + len) throw std::runtime_error(fmt::format("{}: corrupt zip64 extra field", path));
          *f = cd.le(pos, 8);
          pos += 8;
        }
      return;
    }
    at += 4 + len;
  }
}

void check_entry(const ZipEntry& e, uint64_t file_size, const std::string& path) {
  if (e.local_header_offset > file_size || e.compressed_size > file_size - e.local_header_offset)
    throw std::runtime_error(
        fmt::format("{}: truncated or corrupt zip archive (record '{}' of {} bytes at offset {} "
                    "is beyond the file size {})",
                    path, e.name, e.compressed_size, e.local_header_offset, file_size));
  const bool stored_ok = e.method != 0 || e.uncompressed_size == e.compressed_size;
  const bool deflate_ok = e.method != 8 || e.uncompressed_size / kMaxDeflateRatio <= e.compressed_size;
  if (!stored_ok || !deflate_ok)
    throw std::runtime_error(fmt::format("{}: corrupt zip archive (record '{}' claims {} bytes from {} stored bytes)",
                                         path, e.name, e.uncompressed_size, e.compressed_size));
}

}  // namespace

std::vector<ZipEntry> read_zip_directory(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open for reading", path));
  const uint64_t file_size = static_cast<uint64_t>(in.tellg());
  const Directory d = find_directory(in, path, file_size);
  const Bytes cd = read_range(in, path, d.offset, d.size);
  std::vector<ZipEntry> out;
  size_t at = 0;
  for (uint64_t i = 0; i < d.entries; ++i) {
    if (cd.le(at, 4) != kDirectoryEntry)
      throw std::runtime_error(fmt::format("{}: corrupt zip central directory (entry {} of {})", path, i, d.entries));
    ZipEntry e;
    e.method = static_cast<uint16_t>(cd.le(at + 10, 2));
    e.compressed_size = cd.le(at + 20, 4);
    e.uncompressed_size = cd.le(at + 24, 4);
    const size_t name_len = cd.le(at + 28, 2), extra_len = cd.le(at + 30, 2), comment_len = cd.le(at + 32, 2);
    e.local_header_offset = cd.le(at + 42, 4);
    cd.le(at + 46 + name_len + extra_len + comment_len - 1, 1);  // the whole entry lies inside the directory
    e.name = cd.data.substr(at + 46, name_len);
    apply_zip64_extra(cd, at + 46 + name_len, extra_len, e, path);
    check_entry(e, file_size, path);
    out.push_back(std::move(e));
    at += 46 + name_len + extra_len + comment_len;
  }
  return out;
}

}  // namespace uplvsm::io
