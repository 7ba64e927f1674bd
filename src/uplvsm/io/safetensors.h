// Reader and writer for the safetensors format (HuggingFace): 8-byte little-endian header length N, a JSON header
// of N bytes {name: {dtype, shape, data_offsets: [begin, end]}, "__metadata__": {str: str}}, then the raw data.
// Used for model weights, checkpoints and the reference fixtures written by the Python code.
#pragma once
#include <torch/torch.h>

#include <map>
#include <string>

namespace uplvsm::io {

using TensorMap = std::map<std::string, torch::Tensor>;

struct Safetensors {
  TensorMap tensors;                            // CPU, contiguous, in the file's dtype (callers cast)
  std::map<std::string, std::string> metadata;  // the "__metadata__" entry (empty when absent)
};

// One header entry, without the data: for listing a file cheaply.
struct SafetensorsEntry {
  std::string dtype;  // "F32", "BF16", ...
  std::vector<int64_t> shape;
  int64_t begin = 0, end = 0;  // byte offsets into the data buffer
};

// Reads and validates the whole file. Throws std::runtime_error naming the path and the offending field for short
// files, bad header length, invalid JSON, unknown dtypes, negative shapes and out-of-range, overlapping or
// wrongly sized data offsets. Bytes after the last tensor are ignored.
Safetensors read_safetensors(const std::string& path);

// Reads and validates only the header (tensor names -> entries); metadata goes to `metadata` when given.
std::map<std::string, SafetensorsEntry> read_safetensors_header(const std::string& path,
                                                                std::map<std::string, std::string>* metadata = nullptr);

// Writes atomically (temp file + rename). Tensors are made contiguous on the CPU and stored in name order with
// contiguous offsets; the header is padded with spaces to a multiple of 8 bytes, as the Python library does.
void write_safetensors(const std::string& path, const TensorMap& tensors,
                       const std::map<std::string, std::string>& metadata = {});

// "F32" <-> torch::kFloat32 etc.; throws for names/dtypes the format does not have.
torch::Dtype safetensors_dtype_to_torch(const std::string& name);
std::string torch_dtype_to_safetensors(torch::Dtype dtype);

}  // namespace uplvsm::io
