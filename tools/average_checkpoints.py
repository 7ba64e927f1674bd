#!/usr/bin/env python3
"""Uniform average of the model weights of several uplvsm checkpoints of one run (a weight average, the cheap
stand-in for an EMA of the weights). Developer-only (needs numpy).

    python3 tools/average_checkpoints.py OUT.safetensors R/checkpoints/ckpt_A.safetensors R/checkpoints/ckpt_B.safetensors ...

Every fp32 model tensor is the mean of the inputs' (in float64, then rounded to fp32); every other tensor (the
optimiser state, integer buffers) and the header metadata (config, training state) are the last input's, so
`uplvsm eval --checkpoint OUT.safetensors` reads it like any checkpoint. The inputs must hold the same tensors with the
same shapes and dtypes (checkpoints of one run do).
"""
import argparse
import json
import os
import struct
import sys

import numpy as np

OPTIMIZER_PREFIX = "__optimizer__/"


def read_safetensors(path):
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 8:
        sys.exit(f"{path}: not a safetensors file (shorter than its 8-byte header length)")
    n = struct.unpack("<Q", data[:8])[0]
    if 8 + n > len(data):
        sys.exit(f"{path}: header length {n} runs past the end of the file ({len(data)} bytes)")
    header = json.loads(data[8 : 8 + n])
    return header, memoryview(data)[8 + n :]


def tensor_bytes(path, header, body, name):
    start, end = header[name]["data_offsets"]
    if end > len(body):
        sys.exit(f"{path}: tensor {name} runs past the end of the file")
    return body[start:end]


def check_same_tensors(paths, headers):
    names = {k: (v["dtype"], tuple(v["shape"])) for k, v in headers[0].items() if k != "__metadata__"}
    for path, header in zip(paths[1:], headers[1:]):
        other = {k: (v["dtype"], tuple(v["shape"])) for k, v in header.items() if k != "__metadata__"}
        if other != names:
            differing = sorted(set(names.items()) ^ set(other.items()))[:3]
            sys.exit(f"{path}: its tensors differ from {paths[0]}'s (e.g. {differing}): not checkpoints of one run")


def averaged(paths, files, name):
    total = None
    for path, (header, body) in zip(paths, files):
        values = np.frombuffer(tensor_bytes(path, header, body, name), np.float32).astype(np.float64)
        total = values if total is None else total + values
    return (total / len(paths)).astype(np.float32).tobytes()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out")
    parser.add_argument("checkpoints", nargs="+")
    args = parser.parse_args()
    if len(args.checkpoints) < 2:
        sys.exit("give at least two checkpoints to average")
    files = [read_safetensors(p) for p in args.checkpoints]
    check_same_tensors(args.checkpoints, [h for h, _ in files])
    last_path, (last_header, last_body) = args.checkpoints[-1], files[-1]
    header, blobs, offset = {}, [], 0
    for name, info in last_header.items():
        if name == "__metadata__":
            header[name] = info
            continue
        if info["dtype"] == "F32" and not name.startswith(OPTIMIZER_PREFIX):
            raw = averaged(args.checkpoints, files, name)
        else:
            raw = bytes(tensor_bytes(last_path, last_header, last_body, name))
        header[name] = dict(info, data_offsets=[offset, offset + len(raw)])
        blobs.append(raw)
        offset += len(raw)
    encoded = json.dumps(header).encode()
    encoded += b" " * ((8 - len(encoded) % 8) % 8)
    tmp = args.out + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<Q", len(encoded)))
        f.write(encoded)
        for raw in blobs:
            f.write(raw)
    os.replace(tmp, args.out)
    print(f"averaged {len(args.checkpoints)} checkpoints -> {args.out}")


if __name__ == "__main__":
    main()
