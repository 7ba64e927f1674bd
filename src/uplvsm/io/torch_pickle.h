// A bounds-checked interpreter for the subset of Python's pickle that torch.save writes (protocols 2-5): containers,
// scalars, strings, GLOBAL/REDUCE/BUILD and persistent ids for tensor storages. It never executes anything: globals
// it does not know become opaque `Call` objects, so unused parts of a checkpoint (optimiser, scheduler, argparse
// namespaces) never stop a weights load. Tensors stay references (storage key, dtype, view) until asked for.
#pragma once
#include <torch/torch.h>

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace uplvsm::io {

struct PyObject;
using PyPtr = std::shared_ptr<PyObject>;

// A tensor as torch.save describes it: a view of a typed storage that lives elsewhere in the file.
struct TensorRef {
  std::string storage_key;
  torch::Dtype dtype = torch::kFloat32;
  int64_t storage_numel = 0;  // elements of the storage
  int64_t offset = 0;         // elements
  std::vector<int64_t> sizes, strides;
};

struct PyObject {
  enum class Kind { None, Bool, Int, BigInt, Float, Str, Bytes, List, Tuple, Set, Dict, Global, Call, Storage, Tensor };
  Kind kind = Kind::None;
  bool boolean = false;
  int64_t integer = 0;
  double real = 0;
  std::string text;                           // Str, Bytes, BigInt (raw little-endian bytes), Global "module.name"
  std::vector<PyPtr> items;                   // List, Tuple, Set; Call: [callee, args]
  std::vector<std::pair<PyPtr, PyPtr>> dict;  // Dict, in insertion order
  TensorRef tensor;                           // Storage (key, dtype, numel) and Tensor

  PyObject() = default;
  PyObject(const PyObject&) = default;
  PyObject& operator=(const PyObject&) = default;
  // Releases nested containers iteratively: a pickle nests one level per opcode byte, so a recursive release of a
  // deep one would overflow the stack.
  ~PyObject();

  bool is(Kind k) const { return kind == k; }
  // Dict lookup by string key; nullptr when absent or not a dict.
  const PyObject* get(const std::string& key) const;
  std::string describe() const;  // short type name for error messages ("dict", "tensor", "call torch.device", ...)
};

// Maps a persistent id (the tuple torch.save writes for each storage) to a Storage object.
using PersistentLoad = std::function<PyPtr(const PyObject& pid)>;

// Runs the pickle program in data[0, size) starting at `*pos`; on return *pos is just after STOP. Throws
// std::runtime_error naming `source`, the byte offset and the opcode for truncated or malformed input.
PyPtr unpickle(const uint8_t* data, size_t size, size_t* pos, const PersistentLoad& persistent_load,
               const std::string& source);

// "torch.FloatStorage" -> kFloat32, ... (also the dtype objects torch 2.x may reference). Throws for others.
torch::Dtype storage_type_to_dtype(const std::string& global_name);

}  // namespace uplvsm::io
