#!/usr/bin/python3
"""Developer-only check of the C++ preprocessing against Pillow (never used by the product or the tests' normal run).

Writes into OUT_DIR:
  - inputs/*.png: test images (fixture frames decoded by PIL, random noise, sharp edges) of several sizes;
  - expected/*.png: PIL's resize((w, h), LANCZOS) of each input for several target sizes;
  - manifest.json: [{"input", "expected", "width", "height"}];
  - fixture_pixels.json: PIL reference numbers used as constants in tests/data/preprocess_test.cpp.
Then run the C++ comparison:
  UPLVSM_PIL_CHECK_DIR=OUT_DIR build-data/test_data --gtest_filter='Preprocess*Pillow*'

Usage: /usr/bin/python3 tools/check_preprocess.py OUT_DIR [FIXTURES_DIR]
Needs numpy, PIL (apt-get install python3-pil) and torch (to read the chunk fixture).
"""
import io
import json
import os
import sys

import numpy as np
import torch
from PIL import Image


def official_sizes(h0, w0, image_size=224, patch=14):
    # Same expression as the official preprocess_frames.
    wr = round(int(image_size / h0 * w0) / patch) * patch
    return wr, image_size


def main():
    out = sys.argv[1]
    fixtures = sys.argv[2] if len(sys.argv) > 2 else os.path.join(os.path.dirname(__file__), "..", "..", "shared",
                                                                 "fixtures")
    os.makedirs(os.path.join(out, "inputs"), exist_ok=True)
    os.makedirs(os.path.join(out, "expected"), exist_ok=True)
    chunk = torch.load(os.path.join(fixtures, "re10k_chunks", "root", "test", "000000.torch"))
    scene = [s for s in chunk if s["key"] == "20e408dd375292a1"][0]

    inputs = {}
    for f in (0, 7):
        img = Image.open(io.BytesIO(scene["images"][f].numpy().tobytes())).convert("RGB")
        inputs[f"fixture_frame{f}"] = np.asarray(img)
    rng = np.random.default_rng(0)
    inputs["noise_360x640"] = rng.integers(0, 256, (360, 640, 3), dtype=np.uint8)
    inputs["noise_97x131"] = rng.integers(0, 256, (97, 131, 3), dtype=np.uint8)
    edges = np.zeros((200, 300, 3), np.uint8)
    edges[:, ::7] = 255
    edges[::5, :, 1] = 255
    inputs["edges_200x300"] = edges
    inputs["portrait_300x180"] = rng.integers(0, 256, (300, 180, 3), dtype=np.uint8)

    manifest = []
    for name, arr in inputs.items():
        Image.fromarray(arr).save(os.path.join(out, "inputs", name + ".png"))
        h0, w0 = arr.shape[:2]
        targets = {official_sizes(h0, w0), official_sizes(h0, w0, 518), (w0 // 3, h0 // 2), (w0 * 2 + 1, h0 + 3),
                   (w0, h0 // 2), (w0 // 2, h0)}
        for (w, h) in sorted(targets):
            res = Image.fromarray(arr).resize((w, h), Image.LANCZOS)
            exp = f"{name}_{w}x{h}.png"
            res.save(os.path.join(out, "expected", exp))
            manifest.append({"input": "inputs/" + name + ".png", "expected": "expected/" + exp, "width": w,
                             "height": h})
    with open(os.path.join(out, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)

    # Reference numbers for the unit test: PIL decode of frame 0, resize 392x224, crop x from 84 (official 224).
    frame0 = Image.fromarray(inputs["fixture_frame0"])
    wr, hr = official_sizes(360, 640)
    crop = np.asarray(frame0.resize((wr, hr), Image.LANCZOS))[:, (wr - hr) // 2:(wr - hr) // 2 + hr]
    pixels = {f"{r},{c}": crop[r, c].tolist() for (r, c) in [(0, 0), (100, 150), (223, 223), (57, 191)]}
    truth = {"resized": [wr, hr], "crop_start": (wr - hr) // 2, "pixels": pixels,
             "crop_sum": int(crop.astype(np.int64).sum())}
    with open(os.path.join(out, "fixture_pixels.json"), "w") as f:
        json.dump(truth, f, indent=1)
    print(json.dumps(truth))
    print(f"{len(manifest)} resize cases written to {out}")


if __name__ == "__main__":
    main()
