#!/usr/bin/python3
"""Developer-only: writes the seed corpora of the fuzz targets (fuzz/corpus/{chunk,json}).

Chunk seeds are real torch.save files (Debian's python3-torch) of tiny pixelSplat scenes with JPEG frames; JSON
seeds are one valid file per reader, prefixed by the byte that selects the reader in fuzz_json_readers.cpp.
Run from the repository root: /usr/bin/python3 tools/make_fuzz_corpus.py
"""
import io
import json
import os

import torch
from PIL import Image

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fuzz", "corpus")


def jpeg_bytes(w, h, colour):
    buf = io.BytesIO()
    Image.new("RGB", (w, h), colour).save(buf, format="JPEG", quality=80)
    return torch.tensor(list(buf.getvalue()), dtype=torch.uint8)


def png_bytes(w, h, colour):
    buf = io.BytesIO()
    Image.new("RGB", (w, h), colour).save(buf, format="PNG")
    return torch.tensor(list(buf.getvalue()), dtype=torch.uint8)


def camera(n):
    cams = torch.zeros(n, 18)
    cams[:, 0:4] = torch.tensor([0.8, 1.4, 0.5, 0.5])
    cams[:, 6] = cams[:, 11] = cams[:, 16] = 1.0
    cams[:, 9] = torch.arange(n) * 0.1
    return cams


def scene(key, frames, encode):
    return {"url": "https://example.com/" + key, "timestamps": torch.arange(frames) * 33366,
            "cameras": camera(frames), "images": [encode(16, 8, (40 * i, 90, 200)) for i in range(frames)],
            "key": key}


def main():
    chunk_dir, json_dir = os.path.join(ROOT, "chunk"), os.path.join(ROOT, "json")
    os.makedirs(chunk_dir, exist_ok=True)
    os.makedirs(json_dir, exist_ok=True)
    torch.save([scene("00aa11bb22cc33dd", 3, jpeg_bytes)], os.path.join(chunk_dir, "one_scene_jpeg.torch"))
    torch.save([scene("0123456789abcdef", 2, png_bytes), scene("fedcba9876543210", 2, jpeg_bytes)],
               os.path.join(chunk_dir, "two_scenes_png_jpeg.torch"))
    seeds = {
        "eval_index": (0, json.dumps({"a": {"context": [0, 10], "target": [2, 5, 7], "overlap": 0.4}, "b": None})),
        "lvsm_metadata": (1, json.dumps({"scene_name": "scene", "frames": [
            {"image_path": "images/scene/00000.png", "fxfycxcy": [200.0, 200.0, 160.0, 90.0],
             "w2c": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})),
        "subset": (2, json.dumps({"name": "little", "split": "train", "chunks": ["000000.torch"],
                                  "scenes": ["a", "b"], "official_scenes": 1202})),
        "chunk_index": (3, json.dumps({"a": "000000.torch", "b": "000001.torch"})),
        "unposed": (4, json.dumps(["a", "b"])),
        "colmap_cameras": (5, "# Camera list\n1 PINHOLE 640 360 500 500 320 180\n2 SIMPLE_RADIAL 640 360 480 320 180 0.01\n"),
        "transforms": (6, json.dumps({"fl_x": 500, "fl_y": 500, "cx": 320, "cy": 180, "w": 640, "h": 360, "frames": [
            {"file_path": "images/a.png",
             "transform_matrix": [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]}]})),
        "colmap_images": (7, "# Image list\n1 1 0 0 0 0.1 0.2 0.3 1 a.png\n1.0 2.0 -1\n2 0.7071 0 0.7071 0 0 0 1 2 b.png\n\n"),
        "full_list": (8, "/data/re10k/train/metadata/a.json\nmetadata/b.json\n"),
    }
    for name, (selector, text) in seeds.items():
        with open(os.path.join(json_dir, name), "wb") as f:
            f.write(bytes([selector]) + text.encode())


if __name__ == "__main__":
    main()
