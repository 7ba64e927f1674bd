#!/usr/bin/python3
"""Developer-only: writes the seed corpora of the fuzz targets (fuzz/corpus/<target>).

Chunk seeds are real torch.save files (Debian's python3-torch) of tiny pixelSplat scenes with JPEG frames; JSON
seeds are one valid file per reader, prefixed by the byte that selects the reader in fuzz_json_readers.cpp.
Checkpoint seeds are small torch.save files shaped like the official ones (zip and legacy) and safetensors files
(plain and uplvsm checkpoints, written by hand as the format is simple); image seeds cover the JPEG and PNG
variants a decoder branches on; config and camera-path seeds are the repository's configs and a few paths.
Regression seeds (regression_*) are inputs that once crashed a reader: the nested ones are made here, the others
are fuzzer finds kept as they were written (regression_libtorch_zip_uaf.torch, regression_float_as_integer.json).
Run from the repository root: /usr/bin/python3 tools/make_fuzz_corpus.py
"""
import collections
import glob
import io
import json
import os
import struct

import torch
from PIL import Image

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fuzz", "corpus")
FIXTURES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "fixtures")


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


def write(target, name, data):
    os.makedirs(os.path.join(ROOT, target), exist_ok=True)
    with open(os.path.join(ROOT, target, name), "wb") as f:
        f.write(data)


def torch_bytes(obj, zip_format=True):
    buf = io.BytesIO()
    torch.save(obj, buf, _use_new_zipfile_serialization=zip_format)
    return buf.getvalue()


def checkpoint_seeds():
    """Small official-shaped checkpoints: weights under "model", optimiser state, plain values, a strided view."""
    torch.manual_seed(0)
    model = collections.OrderedDict([("tokenizer.weight", torch.randn(4, 3)), ("tokenizer.bias", torch.zeros(4)),
                                     ("head.weight", torch.randn(3, 4).t()), ("steps", torch.tensor(7))])
    ckpt = {"model": model, "optimizer": {"state": {0: {"exp_avg": torch.zeros(4, 3), "step": 5}},
                                          "param_groups": [{"lr": 1e-4, "params": [0, 1]}]},
            "fwdbwd_pass_step": 12, "args": ("a", 1.5, None, True)}
    write("torch_file", "official_like_zip.pt", torch_bytes(ckpt))
    write("torch_file", "official_like_legacy.pt", torch_bytes(ckpt, zip_format=False))
    write("torch_file", "state_dict_half.pt", torch_bytes({"w": torch.randn(2, 2).half(), "b": torch.ones(3).bfloat16(),
                                                         "i": torch.arange(4), "m": torch.ones(2, dtype=torch.bool)}))
    # A one-element storage viewed as 2^36 elements (stride 0): 256 GiB if a reader materialised it.
    write("torch_file", "regression_stride0_view.pt", torch_bytes({"model": {"w": torch.zeros(1).expand(2 ** 36)}}))
    for path in ["lpips/alex.pth", "lpips/vgg.pth"]:
        with open(os.path.join(FIXTURES, path), "rb") as f:
            write("torch_file", os.path.basename(path), f.read())
    for chunk in glob.glob(os.path.join(ROOT, "chunk", "*.torch")):
        with open(chunk, "rb") as f:
            write("torch_file", os.path.basename(chunk), f.read())


def safetensors_bytes(tensors, metadata=None):
    header, data = {}, b""
    if metadata:
        header["__metadata__"] = metadata
    for name, (dtype, shape, raw) in tensors.items():
        header[name] = {"dtype": dtype, "shape": shape, "data_offsets": [len(data), len(data) + len(raw)]}
        data += raw
    text = json.dumps(header).encode()
    text += b" " * ((8 - len(text) % 8) % 8)
    return struct.pack("<Q", len(text)) + text + data


def safetensors_seeds():
    f32 = lambda *v: struct.pack("<%df" % len(v), *v)
    write("safetensors", "plain.safetensors", safetensors_bytes({
        "a": ("F32", [2, 2], f32(1, 2, 3, 4)), "b": ("I64", [1], struct.pack("<q", 7)),
        "c": ("BF16", [2], b"\x80\x3f\x00\x40"), "d": ("U8", [0], b"")}, {"note": "seed"}))
    with open(os.path.join(os.path.dirname(ROOT), "..", "configs", "tiny.json")) as f:
        config = json.load(f)
    state = {"step": 25, "scheduler_step": 25, "param_update_step": 25, "skipped_nonfinite": 0,
             "skipped_gradnorm": 0, "train_seconds": 1.5, "best_eval_psnr": -1}
    write("safetensors", "uplvsm_checkpoint.safetensors", safetensors_bytes({
        "n_light_field_latent": ("F32", [1, 2], f32(0.5, -0.5)),
        "__optimizer__/exp_avg/n_light_field_latent": ("F32", [1, 2], f32(0, 0)),
        "__optimizer__/step/n_light_field_latent": ("I64", [], struct.pack("<q", 25))},
        {"format": "uplvsm-checkpoint-v1", "config": json.dumps(config), "state": json.dumps(state)}))
    with open(os.path.join(FIXTURES, "lpips/lin_alex.safetensors"), "rb") as f:
        write("safetensors", "lin_alex.safetensors", f.read())


def image_seeds():
    gradient = Image.linear_gradient("L").resize((24, 16))
    rgb = Image.merge("RGB", (gradient, gradient.rotate(90).resize((24, 16)), gradient.transpose(Image.FLIP_LEFT_RIGHT)))
    for name, img, fmt, kwargs in [
            ("baseline.jpg", rgb, "JPEG", {"quality": 80}),
            ("progressive.jpg", rgb, "JPEG", {"quality": 70, "progressive": True}),
            ("gray.jpg", gradient, "JPEG", {}),
            ("subsampling444.jpg", rgb, "JPEG", {"subsampling": 0}),
            ("rgb.png", rgb, "PNG", {}),
            ("rgba.png", rgb.convert("RGBA"), "PNG", {}),
            ("gray.png", gradient, "PNG", {}),
            ("palette.png", rgb.convert("P"), "PNG", {}),
            ("interlaced.png", rgb, "PNG", {"interlace": 1}),
            ("gray16.png", gradient.convert("I;16"), "PNG", {})]:
        buf = io.BytesIO()
        img.save(buf, format=fmt, **kwargs)
        write("image", name, buf.getvalue())
    # A JPEG with EXIF focal lengths, as `dataset import` reads them.
    exif = Image.Exif()
    exif[0x920A] = 4.2  # FocalLength (mm)
    buf = io.BytesIO()
    rgb.save(buf, format="JPEG", exif=exif.tobytes())
    write("image", "exif.jpg", buf.getvalue())


def text_seeds():
    for path in glob.glob(os.path.join(os.path.dirname(ROOT), "..", "configs", "*.json")):
        with open(path, "rb") as f:
            write("config", os.path.basename(path), f.read())
    write("camera_path", "poses.json", json.dumps({"units": "baseline", "frames": [
        {"pose": [0, 0, 0, 0, 0, 0, 1], "fxfycxcy": [0.8, 1.4, 0.5, 0.5]},
        {"pose": [0.5, 0, 0.1, 0, 0.0998, 0, 0.995], "fxfycxcy": [0.8, 1.4, 0.5, 0.5]}]}).encode())
    write("camera_path", "c2w.json", json.dumps({"frames": [
        {"c2w": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
        {"c2w": [[0, 0, 1, 1], [0, 1, 0, 0], [-1, 0, 0, 2]]}]}).encode())


def regression_seeds():
    """Nesting one level per byte: recursive code over these overflowed the stack (under AddressSanitizer)."""
    import zipfile
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        stamp = (2026, 1, 1, 0, 0, 0)  # fixed, so the seed is the same on every run
        z.writestr(zipfile.ZipInfo("archive/data.pkl", stamp), b"\x80\x02]" + b"\x85" * 60000 + b".")  # 60000 levels
        z.writestr(zipfile.ZipInfo("archive/version", stamp), b"3\n")
    write("torch_file", "regression_nested_60k.pt", buf.getvalue())
    n = 30000
    write("camera_path", "regression_nested_30k.json", ('{"frames": [{"pose": ' + "[" * n + "]" * n + "}]}").encode())
    write("json", "regression_eval_index_nested_30k",
          b"\x00" + ('{"a": {"context": [' + "[" * n + "]" * n + ', 1], "target": [2]}}').encode())


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
    checkpoint_seeds()
    safetensors_seeds()
    image_seeds()
    text_seeds()
    regression_seeds()


if __name__ == "__main__":
    main()
