#include "binding_util.h"

#include <stdexcept>

#include "uplvsm/core/runtime.h"

namespace uplvsm::python {

torch::Device to_device(const py::handle& device) {
  if (py::isinstance<py::str>(device)) {
    try {
      return parse_device(device.cast<std::string>());
    } catch (const std::exception& e) {
      throw py::value_error(e.what());
    }
  }
  try {
    return device.cast<torch::Device>();
  } catch (const py::cast_error&) {
    throw py::type_error("device: expected a string (\"cpu\", \"cuda\", \"cuda:N\", \"auto\") or a torch.device, got " +
                         std::string(py::str(py::type::of(device))));
  }
}

py::object to_python(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

nlohmann::json to_json(const py::handle& object) {
  std::string text;
  try {
    text = py::module_::import("json").attr("dumps")(object).cast<std::string>();
  } catch (const py::error_already_set& e) {
    throw py::value_error(std::string("config: not JSON-serialisable (") + e.what() + ")");
  }
  return nlohmann::json::parse(text);
}

Config to_config(const py::handle& config) {
  try {
    if (config.is_none()) return Config{};
    if (py::isinstance<py::str>(config) || py::hasattr(config, "__fspath__"))
      return load_config(py::module_::import("os").attr("fspath")(config).cast<std::string>());
    if (py::isinstance<py::dict>(config)) {
      Config c = config_from_json(to_json(config), "config dict");
      validate_config(c, "config dict");
      return c;
    }
  } catch (const py::error_already_set&) {
    throw;
  } catch (const std::exception& e) {
    throw py::value_error(e.what());
  }
  throw py::type_error("config: expected None, a dict or a path to a JSON file, got " +
                       std::string(py::str(py::type::of(config))));
}

void check_tensor(const torch::Tensor& t, const std::string& where, const std::string& name,
                  const std::vector<int64_t>& shape, const std::string& layout) {
  auto fail = [&](const std::string& why) { throw py::value_error(where + ": " + name + " must be " + layout + why); };
  if (!t.defined()) fail(", got None");
  if (!t.is_floating_point()) fail(" of floating point, got " + std::string(c10::toString(t.scalar_type())));
  const bool leading = !shape.empty() && shape[0] == 0;
  const size_t fixed = leading ? shape.size() - 1 : shape.size();
  const size_t dims = static_cast<size_t>(t.dim());
  bool ok = leading ? dims >= fixed : dims == fixed;
  for (size_t i = 0; ok && i < fixed; ++i) {
    const int64_t want = shape[shape.size() - fixed + i];
    ok = want < 0 || t.size(static_cast<int64_t>(dims - fixed + i)) == want;
  }
  if (!ok) fail(", got " + c10::str(t.sizes()));
}

void register_error_translators() {
  // LibTorch's errors carry a C++ backtrace in what(); Python users get the message alone, as the CLI prints it.
  py::register_local_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const c10::ValueError& e) {
      PyErr_SetString(PyExc_ValueError, e.what_without_backtrace());
    } catch (const c10::IndexError& e) {
      PyErr_SetString(PyExc_IndexError, e.what_without_backtrace());
    } catch (const c10::TypeError& e) {
      PyErr_SetString(PyExc_TypeError, e.what_without_backtrace());
    } catch (const c10::Error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what_without_backtrace());
    }
  });
}

}  // namespace uplvsm::python
