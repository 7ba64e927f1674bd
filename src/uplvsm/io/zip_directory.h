// The central directory of a zip archive (torch.save's container), read without decompressing anything: what each
// record claims to hold, so a reader can refuse sizes the file cannot justify before LibTorch's zip reader
// allocates them (it allocates a record's declared size before reading it).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm::io {

struct ZipEntry {
  std::string name;
  uint16_t method = 0;  // 0 stored, 8 deflate
  uint64_t compressed_size = 0, uncompressed_size = 0, local_header_offset = 0;
};

// Parses the end-of-central-directory record (zip64 included) and every central directory entry. Throws
// std::runtime_error naming `path` for a missing or corrupt directory and for entries whose sizes or offsets lie
// outside the file or whose uncompressed size no compression could produce from the stored bytes.
std::vector<ZipEntry> read_zip_directory(const std::string& path);

}  // namespace uplvsm::io
