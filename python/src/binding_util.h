// What every part of the Python bindings shares: argument checks that raise ValueError with the argument's name,
// devices given as strings or torch.device, configs as dicts, and the translation of C++ errors to Python
// exceptions (the library's messages unchanged, without LibTorch's C++ backtraces).
#pragma once
#include <torch/extension.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "uplvsm/core/config.h"

namespace uplvsm::python {

namespace py = pybind11;

// "cpu", "cuda", "cuda:N", "auto" or a torch.device.
torch::Device to_device(const py::handle& device);

// JSON values <-> Python objects (through Python's json module, so numbers and nesting are exactly JSON's).
py::object to_python(const nlohmann::json& j);
nlohmann::json to_json(const py::handle& object);
// A config from None (defaults), a dict (a config file's contents) or a path to a JSON file. Validated; errors name
// the field.
Config to_config(const py::handle& config);

// A floating-point tensor whose shape matches `shape` (-1: any size; a leading 0 entry: that many leading dims of
// any size may come first). Raises ValueError "<where>: <name> must be [..], got [..]".
void check_tensor(const torch::Tensor& t, const std::string& where, const std::string& name,
                  const std::vector<int64_t>& shape, const std::string& layout);

// A dict {name: tensor} in the order given.
template <typename Pairs>
py::dict tensor_dict(const Pairs& pairs) {
  py::dict out;
  for (const auto& [name, tensor] : pairs) out[py::str(name)] = tensor;
  return out;
}

void register_error_translators();

// Each binds one submodule (metrics, io, data) or the model classes into `m`.
void bind_metrics(py::module_& m);
void bind_io(py::module_& m);
void bind_data(py::module_& m);
void bind_model(py::module_& m);

}  // namespace uplvsm::python
