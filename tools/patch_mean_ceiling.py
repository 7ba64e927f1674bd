#!/usr/bin/python3
"""Developer-only analysis of how much PSNR a patch-based renderer needs (never used by the product or the tests).

For every target view of a dataset's evaluation index it scores, against the target at the model resolution:
  - copy: the context view nearer in frame index (the eval baseline);
  - mean: the target's own mean colour (the oracle-constant baseline);
  - block8 / block4: the target's exact mean colour in every 8x8 / 4x4 patch, flat inside the patch - what a model
    that gets each patch token's colour exactly right but draws no texture inside it would score.
Means are over views. The README's "Demo figures" quotes block8 as the bar a patch-8 tiny model must pass.

Usage: /usr/bin/python3 tools/patch_mean_ceiling.py DATASET_ROOT [SIZE=48]
  e.g. /usr/bin/python3 tools/patch_mean_ceiling.py out/demo/dataset 48
Needs numpy, PIL (python3-pil) and torch (to read the chunks).
"""
import io
import json
import os
import sys

import numpy as np
import torch
from PIL import Image


def load_scenes(split_dir):
    scenes = {}
    for name in sorted(os.listdir(split_dir)):
        if name.endswith(".torch"):
            for scene in torch.load(os.path.join(split_dir, name)):
                scenes[scene["key"]] = scene
    return scenes


def view(scene, frame, size):
    # Resize to height `size` (width rounded to a multiple of 8), centre-crop a square: the model's input.
    im = Image.open(io.BytesIO(scene["images"][frame].numpy().tobytes())).convert("RGB")
    w, h = im.size
    new_w = round(w * size / h / 8) * 8
    im = im.resize((new_w, size), Image.LANCZOS)
    left = (new_w - size) // 2
    return np.asarray(im.crop((left, 0, left + size, size)), dtype=np.float64) / 255


def psnr(pred, gt):
    return -10 * np.log10(((pred - gt) ** 2).mean())


def patch_means(gt, patch):
    s = gt.shape[0]
    blocks = gt.reshape(s // patch, patch, s // patch, patch, 3).mean((1, 3), keepdims=True)
    return np.broadcast_to(blocks, (s // patch, patch, s // patch, patch, 3)).reshape(s, s, 3)


def main():
    root = sys.argv[1]
    size = int(sys.argv[2]) if len(sys.argv) > 2 else 48
    index = json.load(open(os.path.join(root, "evaluation_index.json")))
    scenes = load_scenes(os.path.join(root, "test"))
    scores = {"copy": [], "mean": [], "block8": [], "block4": []}
    for key, entry in index.items():
        if entry is None:
            continue
        scene, context = scenes[key], entry["context"]
        for t in entry["target"]:
            gt = view(scene, t, size)
            nearer = context[0] if abs(t - context[0]) <= abs(t - context[1]) else context[1]
            scores["copy"].append(psnr(view(scene, nearer, size), gt))
            scores["mean"].append(psnr(np.broadcast_to(gt.mean((0, 1)), gt.shape), gt))
            scores["block8"].append(psnr(patch_means(gt, 8), gt))
            scores["block4"].append(psnr(patch_means(gt, 4), gt))
    print(root, {name: round(float(np.mean(v)), 2) for name, v in scores.items()})


if __name__ == "__main__":
    main()
