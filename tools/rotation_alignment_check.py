#!/usr/bin/env python3
"""Is a rotation-only alignment a usable teacher on a dataset? (`training.rotation_alignment_weight`, docs/demo.md.)
Developer-only (needs torch; reads PNGs through ImageMagick's `convert`). It uses the ground-truth cameras, which
training never does: it asks whether the term the trainer adds would point the latent rotation the right way.

    uplvsm dataset convert --from chunks --input out/demo/dataset/test --output /tmp/lvsm_test
    python3 tools/rotation_alignment_check.py /tmp/lvsm_test --size 48 --scenes 20

For frame pairs (a, b) of each scene, with K the square-cropped intrinsics and R the real rotation of b in a's
frame, view a is warped as a camera at a's position turned by a rotation and compared with view b (mean squared
difference over the pixels both warps keep), sharp and after a Gaussian blur, as train/rotation_alignment_loss does.
Prints, per blur: how often the real turn scores below no turn; where along the real turn's axis the term is lowest
(0 = no turn, 1 = the real turn); and how often a 1-degree turn towards the real one lowers the term at no turn (the
sign of the gradient a training step starts from).
"""
import argparse
import json
import math
import os
import subprocess

import torch
import torch.nn.functional as F

PAIRS = [(0, 8), (4, 16), (10, 22), (2, 14), (6, 10)]


def read_image(path, size):
    """A PNG as [3, size, size] in [0, 1], centre-cropped to a square and area-resized; returns it and the crop side."""
    ppm = subprocess.run(["convert", path, "ppm:-"], capture_output=True, check=True).stdout
    header = ppm.split(b"\n", 3)
    width, height = map(int, header[1].split())
    x = torch.frombuffer(bytearray(header[3]), dtype=torch.uint8).float().view(height, width, 3).permute(2, 0, 1) / 255
    side = min(width, height)
    top, left = (height - side) // 2, (width - side) // 2
    x = x[:, top:top + side, left:left + side]
    return F.interpolate(x[None], size=(size, size), mode="area")[0], side


def blur(x, sigma):
    if sigma == 0:
        return x
    radius = math.ceil(3 * sigma)
    t = torch.arange(-radius, radius + 1, dtype=torch.float32)
    taps = torch.exp(-t * t / (2 * sigma * sigma))
    taps /= taps.sum()
    x = F.pad(x[None], (radius,) * 4, mode="replicate")
    x = F.conv2d(x, taps.view(1, 1, 1, -1).repeat(3, 1, 1, 1), groups=3)
    return F.conv2d(x, taps.view(1, 1, -1, 1).repeat(3, 1, 1, 1), groups=3)[0]


def warp(view, K, R):
    """What a camera at `view`'s position turned by R sees, and the pixels the warp keeps."""
    size = view.shape[-1]
    ys, xs = torch.meshgrid(torch.arange(size) + 0.5, torch.arange(size) + 0.5, indexing="ij")
    pixels = torch.stack([xs, ys, torch.ones_like(xs)], -1).view(-1, 3)
    rays = R @ (torch.linalg.inv(K) @ pixels.T)
    q = K @ rays
    q = q[:2] / q[2:]
    kept = (rays[2] > 0) & (q[0] >= 0) & (q[0] <= size) & (q[1] >= 0) & (q[1] <= size)
    grid = torch.stack([q[0] / size * 2 - 1, q[1] / size * 2 - 1], -1).view(1, size, size, 2)
    return F.grid_sample(view[None], grid, align_corners=False)[0], kept.view(size, size).float()


def axis_angle(R):
    angle = math.acos(max(-1.0, min(1.0, (R.trace().item() - 1) / 2)))
    axis = torch.tensor([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return axis / axis.norm(), angle


def rotation(axis, angle):
    k = torch.tensor([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return torch.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def term(source, target, K, R, also_kept):
    """The alignment term for rotation R on the pixels its warp keeps and `also_kept` marks."""
    seen, kept = warp(source, K, R)
    kept = kept * also_kept
    return (((seen - target) ** 2 * kept).sum() / (kept.sum() * 3)).item()


def pairs(root, scenes, size):
    """(view a, view b, K, R of b in a's frame) for each pair whose real turn is at least 3 degrees."""
    for name in sorted(os.listdir(os.path.join(root, "metadata")))[:scenes]:
        frames = json.load(open(os.path.join(root, "metadata", name)))["frames"]
        for a, b in PAIRS:
            if b >= len(frames):
                continue
            view_a, side = read_image(frames[a]["image_path"], size)
            view_b, _ = read_image(frames[b]["image_path"], size)
            f = frames[a]["fxfycxcy"][0] * size / side
            K = torch.tensor([[f, 0, size / 2], [0, f, size / 2], [0, 0, 1.0]])
            R = torch.tensor(frames[a]["w2c"])[:3, :3] @ torch.tensor(frames[b]["w2c"])[:3, :3].T
            if axis_angle(R)[1] >= math.radians(3):
                yield view_a, view_b, K, R


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("split", help="a split in the LVSM layout (uplvsm dataset convert --from chunks)")
    parser.add_argument("--size", type=int, default=48, help="the model's image size")
    parser.add_argument("--scenes", type=int, default=20)
    parser.add_argument("--blurs", type=float, nargs="+", default=[0, 3, 6])
    args = parser.parse_args()
    data = list(pairs(args.split, args.scenes, args.size))
    print(f"{len(data)} pairs with a real turn of 3 degrees or more")
    for sigma in args.blurs:
        beats, downhill, best = 0, 0, []
        for view_a, view_b, K, R in data:
            source, target = blur(view_a, sigma), blur(view_b, sigma)
            axis, angle = axis_angle(R)
            none, turned_1 = torch.eye(3), rotation(axis, math.radians(1))
            kept_none, kept_real, kept_1 = (warp(source, K, r)[1] for r in (none, R, turned_1))
            both = kept_none * kept_real
            beats += int(term(source, target, K, R, both) < term(source, target, K, none, both))
            both = kept_none * kept_1
            downhill += int(term(source, target, K, turned_1, both) < term(source, target, K, none, both))
            scores = [(term(source, target, K, rotation(axis, k / 10 * angle), kept_real), k / 10) for k in range(16)]
            best.append(min(scores)[1])
        best.sort()
        n = len(data)
        print(f"blur {sigma:g} px: real turn below no turn in {beats}/{n}; lowest at {best[n // 2]:.1f} of the real "
              f"turn (quartiles {best[n // 4]:.1f}-{best[3 * n // 4]:.1f}); a 1-degree turn towards it lowers the "
              f"term in {downhill}/{n}")


if __name__ == "__main__":
    main()
