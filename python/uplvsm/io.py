"""Files without Python's unpickler: torch.save files (nothing in them is executed), safetensors; images (PNG,
JPEG) and MP4 video."""
from ._uplvsm.io import (OpaqueCall, read_image, read_safetensors, read_torch_file, write_mp4, write_png,
                         write_safetensors)

__all__ = ["read_torch_file", "read_safetensors", "write_safetensors", "read_image", "write_png", "write_mp4",
           "OpaqueCall"]
