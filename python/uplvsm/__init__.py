"""uplvsm: UP-LVSM novel view synthesis (ICLR 2026, "The Less You Depend, The More You Learn") from Python.

The same native code as the `uplvsm` binary, on the LibTorch that `torch` itself loads: tensors go in and out
without copies.

    model = uplvsm.load("uplvsm_x224.pt")            # the authors' checkpoint, or one of ours
    views = uplvsm.data.load_photos(["a.jpg", "b.jpg"], image_size=224)
    video = model.render_interpolation(views["images"], views["fxfycxcy"], num_frames=24)

Submodules: uplvsm.metrics (psnr, ssim, lpips), uplvsm.data (Dataset, load_photos), uplvsm.io (read_torch_file,
read_safetensors, images, MP4).
"""
import ctypes as _ctypes
import os as _os
import sys as _sys

# Debian's LibTorch asks for libblas.so.3, which update-alternatives may point at the reference BLAS (~60x slower
# than OpenBLAS). The uplvsm binaries carry OpenBLAS in DT_RPATH; a Python process cannot, so when torch is not
# loaded yet OpenBLAS is loaded first and LibTorch then binds to it (the loader matches libraries by soname).
_OPENBLAS = "@UPLVSM_OPENBLAS_DIR@/libblas.so.3"
if "torch" not in _sys.modules and _os.path.exists(_OPENBLAS) and not _os.environ.get("UPLVSM_SYSTEM_BLAS"):
    _ctypes.CDLL(_OPENBLAS, mode=_ctypes.RTLD_GLOBAL)

import torch  # noqa: E402  (loads LibTorch and its Python types before the native module uses them)

from ._uplvsm import Model, init_runtime, load, runtime_info  # noqa: E402
from . import data, io, metrics  # noqa: E402

__version__ = "@PROJECT_VERSION@"
__all__ = ["Model", "load", "init_runtime", "runtime_info", "data", "io", "metrics", "__version__"]
