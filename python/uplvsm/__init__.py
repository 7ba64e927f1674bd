"""uplvsm: UP-LVSM novel view synthesis (ICLR 2026, "The Less You Depend, The More You Learn") from Python.

The same native code as the `uplvsm` binary, on the LibTorch that `torch` itself loads: tensors go in and out
without copies.

    model = uplvsm.load("uplvsm_x224.pt")            # the authors' checkpoint, or one of ours
    views = uplvsm.data.load_photos(["a.jpg", "b.jpg"], image_size=224)
    video = model.render_interpolation(views["images"], views["fxfycxcy"], num_frames=24)

Submodules: uplvsm.metrics (psnr, ssim, lpips), uplvsm.data (Dataset, load_photos), uplvsm.io (read_torch_file,
read_safetensors, images, MP4).

Importing uplvsm sets up the process as the uplvsm binary does, process-wide (torch included):
- intra-op threads = the cores this process may use (torch.set_num_threads), unless threads were already chosen
  through OMP_NUM_THREADS or MKL_NUM_THREADS;
- glibc malloc keeps blocks under 1 GiB in the heap (mmap/trim thresholds), so large tensors are not page-faulted
  afresh on every op, unless MALLOC_MMAP_THRESHOLD_ / MALLOC_TRIM_THRESHOLD_ / GLIBC_TUNABLES set them;
- OMP_WAIT_POLICY=PASSIVE when it is unset and torch is not loaded yet (OpenMP workers sleep between parallel
  regions instead of spinning on the cores);
- one RuntimeWarning when the loaded BLAS is slower than the CPU allows (the reference BLAS, OpenBLAS on fallback
  kernels, or OPENBLAS_CORETYPE holding it to weaker ones), naming the variable to set or unset before starting Python.
UPLVSM_RUNTIME=off before the import leaves threads, allocator and OpenMP as they are (init_runtime() still applies
the first two); the warning is given either way.
"""
import ctypes as _ctypes
import os as _os
import sys as _sys

_DEFAULTS = _os.environ.get("UPLVSM_RUNTIME", "auto") != "off"
# libgomp reads OMP_WAIT_POLICY once, when torch loads it: passive workers (the binary's choice) leave the cores to
# other threads and processes between parallel regions.
if _DEFAULTS and "torch" not in _sys.modules and "OMP_WAIT_POLICY" not in _os.environ:
    _os.environ["OMP_WAIT_POLICY"] = "PASSIVE"

# Debian's LibTorch asks for libblas.so.3, which update-alternatives may point at the reference BLAS (~60x slower
# than OpenBLAS). The uplvsm binaries carry OpenBLAS in DT_RPATH; a Python process cannot, so when torch is not
# loaded yet OpenBLAS is loaded first and LibTorch then binds to it (the loader matches libraries by soname).
_OPENBLAS = "@UPLVSM_OPENBLAS_DIR@/libblas.so.3"
if "torch" not in _sys.modules and _os.path.exists(_OPENBLAS) and not _os.environ.get("UPLVSM_SYSTEM_BLAS"):
    _ctypes.CDLL(_OPENBLAS, mode=_ctypes.RTLD_GLOBAL)

import torch  # noqa: E402  (loads LibTorch and its Python types before the native module uses them)

from . import _uplvsm  # noqa: E402
from ._uplvsm import Model, init, init_runtime, load, runtime_info  # noqa: E402
from . import data, io, metrics  # noqa: E402


def _apply_runtime_defaults():
    import warnings

    if _DEFAULTS:
        chosen = any(_os.environ.get(v) for v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"))
        _uplvsm._apply_runtime_defaults(not chosen)
    advice = _uplvsm._blas_warning()
    if advice:
        warnings.warn(advice, RuntimeWarning, stacklevel=2)


_apply_runtime_defaults()

__version__ = "@PROJECT_VERSION@"
__all__ = ["Model", "load", "init", "init_runtime", "runtime_info", "data", "io", "metrics", "__version__"]
