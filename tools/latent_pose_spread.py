#!/usr/bin/env python3
"""How the latent camera spreads against the real one, from a pose-pairs CSV (`uplvsm study pose-pairs`, or the
pairs_*.csv that `uplvsm study pose-probe` writes). Developer-only (needs numpy).

    python3 tools/latent_pose_spread.py out/probe/pairs_test.csv

Prints, over every view but each scene's first input (the canonical frame): the per-axis standard deviation of the
latent and real translations, the mean and spread of the latent and real rotation angles (degrees), and the
correlation of each latent component with each real one. A latent rotation that stays near the identity while the
real one does not is a camera that has not learned to turn.
"""
import argparse
import csv
import sys

import numpy as np

NAMES = ["tx", "ty", "tz", "qx", "qy", "qz", "qw"]


def read(path):
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["frame"] != "0"]
    if not rows:
        sys.exit(f"{path}: no views besides the first inputs")
    latent = np.array([[float(r["latent_" + n]) for n in NAMES] for r in rows])
    real = np.array([[float(r["real_" + n]) for n in NAMES] for r in rows])
    return latent, real


def angle_degrees(q):
    return 2 * np.degrees(np.arccos(np.clip(np.abs(q[:, 3]) / np.linalg.norm(q, axis=1), 0, 1)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("pairs", help="pose-pairs CSV")
    latent, real = read(parser.parse_args().pairs)
    print(f"{len(latent)} views")
    print("translation std   latent " + " ".join(f"{v:.3f}" for v in latent[:, :3].std(0)) +
          "   real " + " ".join(f"{v:.3f}" for v in real[:, :3].std(0)))
    la, ra = angle_degrees(latent[:, 3:]), angle_degrees(real[:, 3:])
    print(f"rotation angle    latent {la.mean():.1f} ± {la.std():.1f} deg   real {ra.mean():.1f} ± {ra.std():.1f} deg")
    print("correlation (rows latent, columns real): " + " ".join(f"{n:>6}" for n in NAMES))
    for j, n in enumerate(NAMES):
        cells = [np.corrcoef(latent[:, j], real[:, k])[0, 1] if latent[:, j].std() > 0 and real[:, k].std() > 0
                 else float("nan") for k in range(7)]
        print(f"{n:>41} " + " ".join(f"{c:+6.2f}" for c in cells))


if __name__ == "__main__":
    main()
