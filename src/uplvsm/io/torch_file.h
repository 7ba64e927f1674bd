// Reader for files written by Python's torch.save, without Python: the zip format (torch >= 1.6: <prefix>/data.pkl,
// <prefix>/data/<key>, <prefix>/version; torch 2.x adds byteorder) — official UP-LVSM checkpoints, DINOv2 *.pth — and
// the legacy pre-zip format (magic, protocol, sys_info and main pickles followed by raw storages) that the LPIPS
// weight files use. LibTorch's torch::pickle_load cannot read the official checkpoint (OrderedDict BUILD), hence
// our own pickle subset (torch_pickle.h). Zip records are read on first use, each storage once, without a copy.
#pragma once
#include <torch/torch.h>

#include <map>
#include <memory>
#include <string>

#include "uplvsm/io/torch_pickle.h"

namespace uplvsm::io {

class TorchFile {
 public:
  // Parses the container and the pickle; reads no tensor data. Throws std::runtime_error naming `path` for files
  // that are not torch.save output, truncated or corrupt archives, big-endian data and malformed pickles.
  explicit TorchFile(const std::string& path);
  ~TorchFile();
  TorchFile(const TorchFile&) = delete;
  TorchFile& operator=(const TorchFile&) = delete;

  const PyObject& root() const;
  const std::string& path() const;
  const std::string& format() const;  // "zip" or "legacy"

  // The tensor a Tensor object refers to (CPU, file dtype, contiguous). Reads its storage on first use. Strided
  // views are copied, within a budget of the file's size over all calls (more is an error).
  torch::Tensor tensor(const PyObject& tensor_object) const;

  // Every tensor value of a dict (keys must be strings); non-tensor values are an error naming the key.
  std::map<std::string, torch::Tensor> tensors(const PyObject& dict, const std::string& where) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// True when the file starts like a torch.save file (zip local header or the legacy pickle magic).
bool looks_like_torch_file(const std::string& path);

// The model weights in a torch.save file: the top-level dict when it holds tensors only (a plain state_dict, as
// DINOv2's and LPIPS's files), otherwise the first of "model", "state_dict", "model_state_dict" that is such a dict
// (official UP-LVSM training checkpoints keep the weights under "model"). `where` receives the key used ("" for
// the top level). Errors list the keys that were found.
std::map<std::string, torch::Tensor> read_torch_state_dict(const std::string& path, std::string* where = nullptr);

}  // namespace uplvsm::io
