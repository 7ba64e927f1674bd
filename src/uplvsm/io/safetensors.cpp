// safetensors reader/writer (see safetensors.h). The reader maps the file read-only and copies each tensor once
// into its own CPU storage, so the returned tensors do not pin the mapping or the file.
#include "uplvsm/io/safetensors.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "uplvsm/io/atomic_file.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "safetensors I/O assumes a little-endian host"
#endif

namespace uplvsm::io {
namespace {

using json = nlohmann::json;

struct DtypeName {
  const char* name;
  torch::Dtype dtype;
};
const DtypeName kDtypes[] = {
    {"F64", torch::kFloat64}, {"F32", torch::kFloat32}, {"F16", torch::kFloat16}, {"BF16", torch::kBFloat16},
    {"I64", torch::kInt64},   {"I32", torch::kInt32},   {"I16", torch::kInt16},   {"I8", torch::kInt8},
    {"U8", torch::kUInt8},    {"BOOL", torch::kBool},
};

std::runtime_error error(const std::string& path, const std::string& what) {
  return std::runtime_error("safetensors '" + path + "': " + what);
}

// A read-only private mapping of a whole file, unmapped on destruction.
struct MappedFile {
  const uint8_t* data = nullptr;
  size_t size = 0;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  explicit MappedFile(const std::string& path) {
    int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw error(path, std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      throw error(path, "not a regular file");
    }
    size = static_cast<size_t>(st.st_size);
    if (size > 0) {
      void* p = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
      if (p == MAP_FAILED) {
        int saved = errno;
        ::close(fd);
        throw error(path, std::string("cannot mmap: ") + std::strerror(saved));
      }
      data = static_cast<const uint8_t*>(p);
      ::madvise(p, size, MADV_SEQUENTIAL);
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data) ::munmap(const_cast<uint8_t*>(data), size);
  }
};

uint64_t read_le_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

int64_t json_int(const std::string& path, const std::string& name, const char* field, const json& v) {
  if (!v.is_number_integer()) throw error(path, "tensor '" + name + "': " + field + " must hold integers");
  return v.get<int64_t>();
}

SafetensorsEntry parse_entry(const std::string& path, const std::string& name, const json& j) {
  if (!j.is_object()) throw error(path, "tensor '" + name + "': header entry must be an object");
  for (const char* field : {"dtype", "shape", "data_offsets"})
    if (!j.contains(field)) throw error(path, "tensor '" + name + "': missing field '" + field + "'");
  SafetensorsEntry e;
  if (!j["dtype"].is_string()) throw error(path, "tensor '" + name + "': dtype must be a string");
  e.dtype = j["dtype"].get<std::string>();
  if (!j["shape"].is_array()) throw error(path, "tensor '" + name + "': shape must be an array");
  for (const json& d : j["shape"]) {
    int64_t n = json_int(path, name, "shape", d);
    if (n < 0) throw error(path, "tensor '" + name + "': negative dimension " + std::to_string(n) + " in shape");
    e.shape.push_back(n);
  }
  const json& off = j["data_offsets"];
  if (!off.is_array() || off.size() != 2) throw error(path, "tensor '" + name + "': data_offsets must be [begin, end]");
  e.begin = json_int(path, name, "data_offsets", off[0]);
  e.end = json_int(path, name, "data_offsets", off[1]);
  if (e.begin < 0 || e.end < e.begin)
    throw error(path, "tensor '" + name + "': invalid data_offsets [" + std::to_string(e.begin) + ", " +
                          std::to_string(e.end) + "]");
  return e;
}

std::map<std::string, std::string> parse_metadata(const std::string& path, const json& j) {
  if (!j.is_object()) throw error(path, "__metadata__ must be an object of strings");
  std::map<std::string, std::string> out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!it.value().is_string()) throw error(path, "__metadata__ value of '" + it.key() + "' must be a string");
    out[it.key()] = it.value().get<std::string>();
  }
  return out;
}

// Checks one entry against the data buffer: known dtype, byte size matches the shape, within the buffer.
void check_entry(const std::string& path, const std::string& name, const SafetensorsEntry& e, uint64_t data_size) {
  torch::Dtype dtype;
  try {
    dtype = safetensors_dtype_to_torch(e.dtype);
  } catch (const std::exception&) {
    throw error(path, "tensor '" + name + "': unknown dtype '" + e.dtype + "'");
  }
  int64_t numel = 1;
  for (int64_t d : e.shape) {
    if (d != 0 && numel > INT64_MAX / d) throw error(path, "tensor '" + name + "': shape too large");
    numel *= d;
  }
  int64_t expected = numel * static_cast<int64_t>(c10::elementSize(dtype));
  if (e.end - e.begin != expected)
    throw error(path, "tensor '" + name + "': data_offsets span " + std::to_string(e.end - e.begin) +
                          " bytes but dtype " + e.dtype + " and shape need " + std::to_string(expected));
  if (static_cast<uint64_t>(e.end) > data_size)
    throw error(path, "tensor '" + name + "': data_offsets end " + std::to_string(e.end) +
                          " is beyond the data buffer (" + std::to_string(data_size) + " bytes)");
}

void check_no_overlap(const std::string& path, const std::map<std::string, SafetensorsEntry>& entries) {
  std::vector<std::pair<const std::string*, const SafetensorsEntry*>> order;
  for (const auto& [name, e] : entries) order.emplace_back(&name, &e);
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
    return std::make_pair(a.second->begin, a.second->end) < std::make_pair(b.second->begin, b.second->end);
  });
  for (size_t i = 1; i < order.size(); ++i) {
    const auto& prev = *order[i - 1].second;
    const auto& cur = *order[i].second;
    if (cur.begin < prev.end)
      throw error(path, "tensors '" + *order[i - 1].first + "' and '" + *order[i].first + "' have overlapping data");
  }
}

// Parses the header from the first bytes of the file; `header_end` receives the start of the data buffer.
std::map<std::string, SafetensorsEntry> parse_header(const std::string& path, const uint8_t* data, size_t size,
                                                     std::map<std::string, std::string>* metadata, size_t* header_end) {
  if (size < 8) throw error(path, "file is " + std::to_string(size) + " bytes, shorter than the 8-byte header length");
  uint64_t n = read_le_u64(data);
  if (n > size - 8)
    throw error(path, "header length " + std::to_string(n) + " is beyond the file size " + std::to_string(size));
  json header;
  try {
    header = json::parse(reinterpret_cast<const char*>(data + 8), reinterpret_cast<const char*>(data + 8 + n));
  } catch (const json::exception& ex) {
    throw error(path, std::string("invalid JSON header: ") + ex.what());
  }
  if (!header.is_object()) throw error(path, "JSON header must be an object");
  std::map<std::string, SafetensorsEntry> entries;
  for (auto it = header.begin(); it != header.end(); ++it) {
    if (it.key() == "__metadata__") {
      auto md = parse_metadata(path, it.value());
      if (metadata) *metadata = std::move(md);
      continue;
    }
    entries[it.key()] = parse_entry(path, it.key(), it.value());
  }
  uint64_t data_size = size - 8 - n;
  for (const auto& [name, e] : entries) check_entry(path, name, e, data_size);
  check_no_overlap(path, entries);
  *header_end = 8 + n;
  return entries;
}

std::string dims_json(const torch::Tensor& t) {
  json shape = json::array();
  for (int64_t d : t.sizes()) shape.push_back(d);
  return shape.dump();
}

}  // namespace

torch::Dtype safetensors_dtype_to_torch(const std::string& name) {
  for (const auto& d : kDtypes)
    if (name == d.name) return d.dtype;
  throw std::runtime_error("safetensors: unknown dtype '" + name + "'");
}

std::string torch_dtype_to_safetensors(torch::Dtype dtype) {
  for (const auto& d : kDtypes)
    if (dtype == d.dtype) return d.name;
  throw std::runtime_error(std::string("safetensors: dtype ") + c10::toString(dtype) + " cannot be stored");
}

std::map<std::string, SafetensorsEntry> read_safetensors_header(const std::string& path,
                                                                std::map<std::string, std::string>* metadata) {
  MappedFile file(path);
  size_t header_end = 0;
  return parse_header(path, file.data, file.size, metadata, &header_end);
}

Safetensors read_safetensors(const std::string& path) {
  MappedFile file(path);
  Safetensors out;
  size_t header_end = 0;
  auto entries = parse_header(path, file.data, file.size, &out.metadata, &header_end);
  const uint8_t* buffer = file.data + header_end;
  for (const auto& [name, e] : entries) {
    torch::Tensor t = torch::empty(e.shape, torch::TensorOptions().dtype(safetensors_dtype_to_torch(e.dtype)));
    if (e.end > e.begin) std::memcpy(t.data_ptr(), buffer + e.begin, static_cast<size_t>(e.end - e.begin));
    out.tensors.emplace(name, std::move(t));
  }
  return out;
}

void write_safetensors(const std::string& path, const TensorMap& tensors,
                       const std::map<std::string, std::string>& metadata) {
  // Header built by hand so "__metadata__" comes first and tensors keep name order, like the Python writer.
  std::vector<torch::Tensor> contiguous;
  std::string header = "{";
  if (!metadata.empty()) header += "\"__metadata__\":" + json(metadata).dump();
  int64_t offset = 0;
  for (const auto& [name, tensor] : tensors) {
    if (name == "__metadata__") throw error(path, "'__metadata__' is reserved and cannot name a tensor");
    if (!tensor.defined()) throw error(path, "tensor '" + name + "' is undefined");
    std::string dtype;
    try {
      dtype = torch_dtype_to_safetensors(tensor.scalar_type());
    } catch (const std::exception& ex) {
      throw error(path, "tensor '" + name + "': " + ex.what());
    }
    torch::Tensor t = tensor.detach().to(torch::kCPU).contiguous();
    int64_t bytes = t.numel() * static_cast<int64_t>(t.element_size());
    if (header.size() > 1) header += ",";
    header += json(name).dump() + ":{\"dtype\":\"" + dtype + "\",\"shape\":" + dims_json(t) + ",\"data_offsets\":[" +
              std::to_string(offset) + "," + std::to_string(offset + bytes) + "]}";
    offset += bytes;
    contiguous.push_back(std::move(t));
  }
  header += "}";
  header.append((8 - header.size() % 8) % 8, ' ');
  uint8_t len[8];
  for (int i = 0; i < 8; ++i) len[i] = static_cast<uint8_t>(static_cast<uint64_t>(header.size()) >> (8 * i));
  std::vector<ByteSpan> parts{{len, 8}, {header.data(), header.size()}};
  for (const auto& t : contiguous) parts.push_back({t.data_ptr(), static_cast<size_t>(t.numel()) * t.element_size()});
  write_file_atomic(path, parts);
}

}  // namespace uplvsm::io
