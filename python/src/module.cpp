// The native part of the `uplvsm` Python package (uplvsm/_uplvsm*.so): built against the LibTorch that Debian's
// python3-torch loads, so tensors pass between Python and C++ as they are (no copies). Python files in
// python/uplvsm/ import this and give the public names.
#include "binding_util.h"
#include "uplvsm/core/runtime.h"

namespace py = pybind11;
using namespace uplvsm::python;

PYBIND11_MODULE(_uplvsm, m) {
  m.doc() = "uplvsm: UP-LVSM novel view synthesis (native C++/LibTorch) - the model, metrics, datasets and readers.";
  register_error_translators();
  m.def(
      "init_runtime",
      [](int threads) {
        if (threads < 0) throw py::value_error("init_runtime: threads must be >= 0 (0: every core available)");
        uplvsm::init_runtime(threads);
      },
      py::arg("threads") = 0,
      R"(What the uplvsm binary does at start: intra-op threads (0: every core this process may use), one inter-op
thread, and glibc malloc keeping blocks under 1 GiB in the heap (large tensors are not page-faulted afresh on every
op). Process-wide: it applies to torch too.)");
  m.def(
      "_apply_runtime_defaults", [](bool set_threads) { uplvsm::init_library_runtime(set_threads); },
      py::arg("set_threads"),
      "What `import uplvsm` applies (see uplvsm.__init__): allocator thresholds, and intra-op threads when asked.");
  m.def(
      "_blas_warning",
      [] {
        return uplvsm::blas_warning(uplvsm::runtime_info(), uplvsm::detect_cpu_features(),
                                    std::getenv("OPENBLAS_CORETYPE"));
      },
      "The warning `import uplvsm` gives when the loaded BLAS is slower than this CPU allows (\"\" when fine).");
  m.def(
      "runtime_info",
      [] {
        const auto i = uplvsm::runtime_info();
        py::dict d;
        d["torch_version"] = i.torch_version;
        d["blas_library"] = i.blas_library;
        d["blas_core"] = i.blas_core;
        d["threads"] = i.threads;
        d["interop_threads"] = i.interop_threads;
        d["omp_wait_policy"] = i.omp_wait_policy;
        d["allocator"] = i.allocator;
        d["cpu_features"] = i.cpu_features;
        d["cuda_devices"] = i.cuda_devices;
        return d;
      },
      "LibTorch version, the BLAS library loaded, threads, CPU features, OpenMP wait policy, allocator, CUDA devices.");
  bind_metrics(m);
  bind_io(m);
  bind_data(m);
  bind_model(m);
}
