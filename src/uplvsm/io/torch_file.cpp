#include "uplvsm/io/torch_file.h"

#include <caffe2/serialize/inline_container.h>

#include <cstring>
#include <fstream>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/zip_directory.h"

namespace uplvsm::io {

using Kind = PyObject::Kind;

namespace {

// The legacy format's first pickle: LONG1 0x1950a86a20f9469cfc6c (little-endian bytes).
const std::string kLegacyMagic("\x6c\xfc\x9c\x46\xf9\x20\x6a\xa8\x50\x19", 10);

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open for reading", path));
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// ('storage', storage_type, key, location, numel[, view_metadata]) -> Storage object.
PyPtr storage_from_pid(const PyObject& pid) {
  if (pid.kind != Kind::Tuple || pid.items.size() < 5 || !pid.items[0]->is(Kind::Str) ||
      pid.items[0]->text != "storage")
    throw std::runtime_error("persistent id is not a ('storage', type, key, location, numel) tuple");
  const auto& type = *pid.items[1];
  const auto& key = *pid.items[2];
  const auto& numel = *pid.items[4];
  if (!type.is(Kind::Global)) throw std::runtime_error("storage type is " + type.describe() + ", expected a global");
  if (!key.is(Kind::Str)) throw std::runtime_error("storage key is " + key.describe() + ", expected a str");
  if (!numel.is(Kind::Int) || numel.integer < 0 || numel.integer > (int64_t(1) << 48))
    throw std::runtime_error("storage size is not an int in [0, 2^48]");
  if (pid.items.size() > 5 && !pid.items[5]->is(Kind::None))
    throw std::runtime_error("storage views (pre-1.0 torch files) are not supported");
  auto s = std::make_shared<PyObject>();
  s->kind = Kind::Storage;
  s->tensor.storage_key = key.text;
  s->tensor.dtype = storage_type_to_dtype(type.text);
  s->tensor.storage_numel = numel.integer;
  return s;
}

}  // namespace

struct TorchFile::Impl {
  std::string path, format;
  PyPtr root;
  // Bytes that copies of strided views may still allocate: a view can repeat stored values (stride 0, or one
  // tensor referenced many times), so without a budget a small file could demand any amount of memory.
  mutable int64_t copy_budget = 0;
  std::map<std::string, TensorRef> storages;            // key -> storage (dtype, numel), from the pickle
  mutable std::map<std::string, torch::Tensor> loaded;  // key -> 1-D storage tensor
  // zip
  std::unique_ptr<caffe2::serialize::PyTorchStreamReader> zip;
  // legacy: the whole file and each storage's data offset
  std::string bytes;
  std::map<std::string, size_t> legacy_offsets;

  PersistentLoad recorder() {
    return [this](const PyObject& pid) {
      auto s = storage_from_pid(pid);
      auto [it, inserted] = storages.emplace(s->tensor.storage_key, s->tensor);
      if (!inserted && (it->second.dtype != s->tensor.dtype || it->second.storage_numel != s->tensor.storage_numel))
        throw std::runtime_error(
            fmt::format("storage '{}' is described twice with different types", s->tensor.storage_key));
      return s;
    };
  }

  void open_zip() {
    format = "zip";
    // LibTorch's reader allocates each record's declared size: check every declaration against the file first.
    read_zip_directory(path);
    try {
      zip = std::make_unique<caffe2::serialize::PyTorchStreamReader>(path);
      if (zip->hasRecord("byteorder")) {
        auto [ptr, n] = zip->getRecord("byteorder");
        std::string order(static_cast<const char*>(ptr.get()), n);
        if (order != "little")
          throw std::runtime_error(
              fmt::format("{}: byteorder '{}' (only little-endian files are supported)", path, order));
      }
      if (!zip->hasRecord("data.pkl"))
        throw std::runtime_error(
            fmt::format("{}: zip archive has no data.pkl (not a torch.save file; TorchScript "
                        "archives are not supported)",
                        path));
      auto [ptr, n] = zip->getRecord("data.pkl");
      size_t pos = 0;
      root = unpickle(static_cast<const uint8_t*>(ptr.get()), n, &pos, recorder(), path + " data.pkl");
    } catch (const c10::Error& e) {
      throw std::runtime_error(
          fmt::format("{}: corrupt or truncated torch zip archive ({})", path, e.what_without_backtrace()));
    }
  }

  void open_legacy() {
    format = "legacy";
    const auto* d = reinterpret_cast<const uint8_t*>(bytes.data());
    size_t pos = 0;
    PersistentLoad none = [](const PyObject&) -> PyPtr { throw std::runtime_error("unexpected persistent id"); };
    auto magic = unpickle(d, bytes.size(), &pos, none, path + " (magic number)");
    if (!magic->is(Kind::BigInt) || magic->text != kLegacyMagic)
      throw std::runtime_error(fmt::format("{}: not a torch.save file (bad magic number)", path));
    auto protocol = unpickle(d, bytes.size(), &pos, none, path + " (protocol)");
    if (!protocol->is(Kind::Int) || protocol->integer != 1001)
      throw std::runtime_error(fmt::format("{}: legacy protocol version is not 1001", path));
    auto sys_info = unpickle(d, bytes.size(), &pos, none, path + " (sys_info)");
    if (const auto* le = sys_info->get("little_endian"); le && le->is(Kind::Bool) && !le->boolean)
      throw std::runtime_error(fmt::format("{}: written on a big-endian machine (not supported)", path));
    root = unpickle(d, bytes.size(), &pos, recorder(), path);
    auto keys = unpickle(d, bytes.size(), &pos, none, path + " (storage keys)");
    if (!keys->is(Kind::List))
      throw std::runtime_error(fmt::format("{}: storage key list is {}", path, keys->describe()));
    for (const auto& key : keys->items) {
      if (!key->is(Kind::Str) || !storages.count(key->text))
        throw std::runtime_error(fmt::format("{}: storage key list names a storage the pickle never used", path));
      const auto& s = storages.at(key->text);
      if (bytes.size() - pos < 8)
        throw std::runtime_error(fmt::format("{}: truncated before storage '{}'", path, key->text));
      int64_t count = 0;
      std::memcpy(&count, d + pos, 8);
      if (count != s.storage_numel)
        throw std::runtime_error(fmt::format("{}: storage '{}' holds {} elements, the pickle says {}", path, key->text,
                                             count, s.storage_numel));
      size_t nbytes = size_t(count) * c10::elementSize(s.dtype);
      if (bytes.size() - pos - 8 < nbytes)
        throw std::runtime_error(
            fmt::format("{}: truncated inside storage '{}' ({} bytes expected)", path, key->text, nbytes));
      legacy_offsets[key->text] = pos + 8;
      pos += 8 + nbytes;
    }
  }

  torch::Tensor storage(const TensorRef& ref) const {
    auto hit = loaded.find(ref.storage_key);
    if (hit != loaded.end()) return hit->second;
    const int64_t nbytes = ref.storage_numel * int64_t(c10::elementSize(ref.dtype));
    auto options = torch::TensorOptions().dtype(ref.dtype);
    torch::Tensor out;
    if (format == "zip") {
      std::string record = "data/" + ref.storage_key;
      try {
        if (!zip->hasRecord(record))
          throw std::runtime_error(fmt::format("{}: record '{}' is missing from the archive", path, record));
        auto [ptr, n] = zip->getRecord(record);
        if (int64_t(n) < nbytes)
          throw std::runtime_error(fmt::format("{}: record '{}' has {} bytes, {} expected", path, record, n, nbytes));
        auto holder = std::make_shared<at::DataPtr>(std::move(ptr));
        out = torch::from_blob(
            holder->get(), {ref.storage_numel}, [holder](void*) {}, options);
      } catch (const c10::Error& e) {
        throw std::runtime_error(fmt::format("{}: cannot read '{}' ({})", path, record, e.what_without_backtrace()));
      }
    } else {
      auto off = legacy_offsets.find(ref.storage_key);
      if (off == legacy_offsets.end())
        throw std::runtime_error(fmt::format("{}: storage '{}' has no data in the file", path, ref.storage_key));
      out = torch::empty({ref.storage_numel}, options);
      std::memcpy(out.data_ptr(), bytes.data() + off->second, size_t(nbytes));
    }
    loaded[ref.storage_key] = out;
    return out;
  }
};

TorchFile::TorchFile(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open for reading", path));
  impl_->copy_budget = static_cast<int64_t>(in.tellg());
  in.seekg(0);
  char head[4] = {0, 0, 0, 0};
  in.read(head, 4);
  in.close();
  if (std::memcmp(head, "PK\x03\x04", 4) == 0) {
    impl_->open_zip();
  } else if (uint8_t(head[0]) == 0x80) {
    impl_->bytes = read_all(path);
    impl_->open_legacy();
  } else {
    throw std::runtime_error(
        fmt::format("{}: not a torch.save file (neither a zip archive nor a legacy pickle)", path));
  }
}

TorchFile::~TorchFile() = default;

const PyObject& TorchFile::root() const { return *impl_->root; }
const std::string& TorchFile::path() const { return impl_->path; }
const std::string& TorchFile::format() const { return impl_->format; }

torch::Tensor TorchFile::tensor(const PyObject& t) const {
  if (!t.is(Kind::Tensor))
    throw std::runtime_error(fmt::format("{}: expected a tensor, got {}", impl_->path, t.describe()));
  auto storage = impl_->storage(t.tensor);
  auto view = storage.as_strided(t.tensor.sizes, t.tensor.strides, t.tensor.offset);
  if (view.is_contiguous()) return view;
  const int64_t bytes = view.numel() * int64_t(view.element_size());
  if (bytes > impl_->copy_budget)
    throw std::runtime_error(
        fmt::format("{}: strided tensor views would copy more bytes than the file holds ({} more "
                    "needed, {} left)",
                    impl_->path, bytes, impl_->copy_budget));
  impl_->copy_budget -= bytes;
  return view.contiguous();
}

std::map<std::string, torch::Tensor> TorchFile::tensors(const PyObject& dict, const std::string& where) const {
  if (!dict.is(Kind::Dict))
    throw std::runtime_error(
        fmt::format("{}: {} is {}, expected a dict of tensors", impl_->path, where, dict.describe()));
  std::map<std::string, torch::Tensor> out;
  for (const auto& [k, v] : dict.dict) {
    if (!k->is(Kind::Str)) throw std::runtime_error(fmt::format("{}: {} has a non-string key", impl_->path, where));
    if (!v->is(Kind::Tensor))
      throw std::runtime_error(
          fmt::format("{}: {}['{}'] is {}, expected a tensor", impl_->path, where, k->text, v->describe()));
    if (!out.emplace(k->text, tensor(*v)).second)
      throw std::runtime_error(fmt::format("{}: {} repeats key '{}'", impl_->path, where, k->text));
  }
  return out;
}

bool looks_like_torch_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[14] = {};
  in.read(head, sizeof head);
  if (in.gcount() >= 4 && std::memcmp(head, "PK\x03\x04", 4) == 0) return true;
  return in.gcount() == 14 && uint8_t(head[0]) == 0x80 && uint8_t(head[2]) == 0x8a && uint8_t(head[3]) == 0x0a &&
         std::memcmp(head + 4, kLegacyMagic.data(), 10) == 0;
}

namespace {
bool all_tensors(const PyObject& dict) {
  if (!dict.is(Kind::Dict) || dict.dict.empty()) return false;
  for (const auto& [k, v] : dict.dict)
    if (!k->is(Kind::Str) || !v->is(Kind::Tensor)) return false;
  return true;
}
}  // namespace

std::map<std::string, torch::Tensor> read_torch_state_dict(const std::string& path, std::string* where) {
  TorchFile file(path);
  const auto& root = file.root();
  if (all_tensors(root)) {
    if (where) *where = "";
    return file.tensors(root, "the top-level dict");
  }
  for (const char* key : {"model", "state_dict", "model_state_dict"}) {
    const auto* sub = root.get(key);
    if (sub && all_tensors(*sub)) {
      if (where) *where = key;
      return file.tensors(*sub, fmt::format("['{}']", key));
    }
  }
  std::string keys;
  if (root.is(Kind::Dict))
    for (const auto& [k, v] : root.dict)
      keys += fmt::format(" '{}' ({})", k->is(Kind::Str) ? k->text : "?", v->describe());
  throw std::runtime_error(
      fmt::format("{}: no state dict found: the top level is {} and none of 'model', 'state_dict', "
                  "'model_state_dict' holds a dict of tensors; keys found:{}",
                  path, root.describe(), keys.empty() ? " none" : keys));
}

}  // namespace uplvsm::io
