#!/usr/bin/env python3
"""Times, or exports to ONNX, the authors' own UP-LVSM (github.com/ou524u/Less3Depend, `unposedLVSM`) at x224 on
the CPU, for the comparison that `bench/cpu_sitting.sh` runs against ONNX Runtime and our `uplvsm_bench`.

What it measures: the official model built from the official config (default `config/uplvsm_x224.yaml`: d 768,
d_head 64, encoder/estimator/decoder 6/4/14 blocks, 1024 latents, DINOv2 ViT-B/14 with 4 registers and QK-norm)
with random weights (seeded; no checkpoint and no pretrained DINOv2 are loaded, timing does not depend on the
values), in eval mode, fp32, no autocast, under torch.no_grad(), torch.set_num_threads(--threads, default 2). One
forward is the official evaluation forward `model(batch, has_target_image=True, target_has_input=False)` on a batch
of 1 scene of 5 views at 224x224: views 0-1 are the inputs, views 2-4 the targets (the official eval rule), the
estimator reads the targets' images, the decoder renders 3 target views. The inputs are what our
`Inference/paper_x224` benchmark feeds: torch.rand images (seed 0) in [0, 1], fx = fy = 0.9 * 224,
cx = cy = 0.5 * 224 for every view; c2w is the identity (the unposed model's outputs do not depend on it).
`--time N` runs --warmup forwards (default 1, as uplvsm_bench does), then N timed forwards, and prints seconds per
target view (forward time / 3) of each, their median and mean; `--export-onnx FILE` writes the same forward
(inputs: images [1, 5, 3, 224, 224], fxfycxcy [1, 5, 4], c2w [1, 5, 4, 4]; output: render [1, 3, 3, 224, 224])
at opset 17, with FILE.io/ holding the inputs and torch's output as raw little-endian float32 for
`bench/ort_x224.mjs`, checks it with onnx.checker when the onnx package is installed, and prints the max abs
difference between torch's output and the exported model's (onnxruntime's Python API if installed, else
`node bench/ort_x224.mjs FILE --check` when --ort-dir is given).

It needs the official code (--official DIR, a checkout of ou524u/Less3Depend; measured at commit d490397) and
einops, which this script does not ship: the real package or a stand-in on --shims DIR / PYTHONPATH that provides
`einops.rearrange`, `einops.repeat` and `einops.layers.torch.Rearrange` for the patterns the model uses
("b v c h w -> (b v) c h w", "b v c (hh ph) (ww pw) -> (b v) (hh ww) (ph pw c)", "b l (nh dh) -> b l nh dh",
"b l nh dh -> b l (nh dh)", "b nl d -> (b v_target) nl d", "(b v) d -> b v d",
"(b v) (h w) (p1 p2 c) -> b v c (h p1) (w p2)", "(b v) (h w) c -> b v c h w"). Also easydict and PyYAML
(Debian: python3-easydict, python3-yaml); python3-onnx for the checker. Nothing of the official code is copied here;
the script imports it and changes, at run time and only for this process, what cannot run on a CPU or on torch
1.13 (printed on start-up; none changes the forward's arithmetic):
  - xformers (CUDA only; its flash op is what the official transformer blocks call): memory_efficient_attention is
    replaced by exact softmax attention with scale d_head**-0.5, no mask, no dropout — torch's
    F.scaled_dot_product_attention where torch has it (>= 2.0), else softmax(q k^T * scale) v;
  - torch < 2.0: F.scaled_dot_product_attention (used by the DINOv2 blocks) is added as that same exact attention;
  - torch < 2.1: nn.LayerNorm accepts bias= (bias=False: no bias, as F.layer_norm(..., bias=None));
  - the DINOv2 tokenizer is built with the official constructor arguments (vit_base, img 518, patch 14,
    4 registers, antialiased bicubic pos-embed interpolation, offset 0, init_values 1, qk_norm from the config)
    without downloading/loading the pretrained file; its unused mask_token is deleted as the official code does;
  - `rays_from_c2w` as the model module calls it gets device=c2w.device (its default is "cuda");
  - the training-only perceptual (VGG19) and LPIPS loss weights are set to 0, so no VGG is built or run (the
    official inference computes the loss inside forward; the L2 loss/PSNR on the 3 targets stays, ~1 ms);
  - modules the forward does not use (lpips, jaxtyping, imageio, scipy.io, torchvision) get empty stand-ins only
    when they are not installed.
  For the ONNX export only: the DINOv2 positional embedding, a function of the weights alone, is interpolated once
  by the official method and then reused (ONNX has no antialiased bicubic resize); the gradient checkpointing
  wrapper (a no-op under no_grad) is bypassed; bias-less LayerNorms get an explicit zero bias (torch 1.13 writes
  LayerNormalization's absent bias as "", on which ONNX Runtime's SkipLayerNormFusion segfaults at optimisation
  level extended/all — seen with onnxruntime-node 1.20.1, 1.22.0 and 1.31.1). Timing runs keep all three as the
  official code has them.

Commands (repository root; shims dir with the einops stand-in):
    OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE /usr/bin/python3 bench/official_x224.py \
        --official /tmp/official --shims /tmp/official_shims --time 3
    /usr/bin/python3 bench/official_x224.py --official /tmp/official --shims /tmp/official_shims \
        --export-onnx /tmp/uplvsm_official_x224.onnx [--ort-dir /tmp/ort]
"""
import argparse
import functools
import importlib
import inspect
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import time
import types

INPUT_VIEWS, TARGET_VIEWS = 2, 3
REPO = pathlib.Path(__file__).resolve().parents[1]


def log(message):
    print(f"[official_x224] {message}", file=sys.stderr, flush=True)


def exact_attention_bhld(q, k, v, scale):
    """softmax(q k^T * scale) v on [B, H, L, D] (the textbook attention; no mask, no dropout)."""
    import torch
    attn = torch.matmul(q * scale, k.transpose(-2, -1)).softmax(dim=-1)
    return torch.matmul(attn, v)


def install_runtime_patches(use_sdpa):
    """The run-time stand-ins listed in the module docstring. Returns a list of lines describing them."""
    import torch
    import torch.nn as nn
    import torch.nn.functional as F

    notes = []
    has_sdpa = hasattr(F, "scaled_dot_product_attention")
    if not has_sdpa:
        def scaled_dot_product_attention(query, key, value, attn_mask=None, dropout_p=0.0, is_causal=False,
                                         scale=None):
            if attn_mask is not None or is_causal or dropout_p:
                raise NotImplementedError("stand-in SDPA: no mask, no causal, no dropout")
            s = query.shape[-1] ** -0.5 if scale is None else scale
            return exact_attention_bhld(query, key, value, s)
        F.scaled_dot_product_attention = scaled_dot_product_attention
        notes.append("torch has no F.scaled_dot_product_attention: added as exact softmax attention (DINOv2)")
    sdpa = use_sdpa and has_sdpa

    def memory_efficient_attention(query, key, value, attn_bias=None, p=0.0, scale=None, op=None):
        # xformers layout [B, L, H, D]; default scale D**-0.5
        if attn_bias is not None or p:
            raise NotImplementedError("xformers stand-in: no attn_bias, no dropout")
        q, k, v = (t.transpose(1, 2) for t in (query, key, value))
        s = query.shape[-1] ** -0.5 if scale is None else scale
        if sdpa:
            out = F.scaled_dot_product_attention(q, k, v, scale=s) if scale is not None else \
                F.scaled_dot_product_attention(q, k, v)
        else:
            out = exact_attention_bhld(q, k, v, s)
        return out.transpose(1, 2)

    xformers = types.ModuleType("xformers")
    xops = types.ModuleType("xformers.ops")
    xops.memory_efficient_attention = memory_efficient_attention
    xops.fmha = types.SimpleNamespace(flash=types.SimpleNamespace(FwOp=None, BwOp=None))
    xformers.ops = xops
    sys.modules["xformers"], sys.modules["xformers.ops"] = xformers, xops
    notes.append("xformers.ops.memory_efficient_attention -> "
                 + ("torch F.scaled_dot_product_attention" if sdpa else "exact softmax(q k^T / sqrt(d)) v"))

    if "bias" not in inspect.signature(nn.LayerNorm.__init__).parameters:
        base = nn.LayerNorm

        class LayerNorm(base):
            def __init__(self, normalized_shape, eps=1e-5, elementwise_affine=True, bias=True, device=None,
                         dtype=None):
                super().__init__(normalized_shape, eps=eps, elementwise_affine=elementwise_affine, device=device,
                                 dtype=dtype)
                if not bias and elementwise_affine:
                    del self.bias
                    self.register_parameter("bias", None)

        nn.LayerNorm = LayerNorm
        notes.append("nn.LayerNorm accepts bias= (torch < 2.1)")

    def stub(name, **attrs):
        try:
            importlib.import_module(name)
            return
        except ImportError:
            pass
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        sys.modules[name] = module
        parent, _, child = name.rpartition(".")
        if parent:
            setattr(sys.modules[parent], child, module)
        notes.append(f"'{name}' not installed: empty stand-in (unused by the forward)")

    def unavailable(what):
        def f(*args, **kwargs):
            raise RuntimeError(f"{what} is a stand-in in bench/official_x224.py")
        return f

    class _Annotation:
        def __getitem__(self, item):
            return object

    stub("lpips", LPIPS=unavailable("lpips.LPIPS"))
    stub("jaxtyping", Float=_Annotation(), Int=_Annotation(), Bool=_Annotation())
    stub("imageio", mimsave=unavailable("imageio.mimsave"))
    stub("scipy")
    stub("scipy.io", loadmat=unavailable("scipy.io.loadmat"))
    stub("torchvision")
    stub("torchvision.models", vgg19=unavailable("torchvision.models.vgg19"))
    return notes


def load_config(path):
    import yaml
    from easydict import EasyDict as edict
    with open(path) as f:
        config = yaml.safe_load(f)["parameters"]
    config = edict(config)
    config.training.perceptual_loss_weight = 0.0
    config.training.lpips_loss_weight = 0.0
    return config


def build_model(official, config_path, seed, use_sdpa):
    official = pathlib.Path(official).resolve()
    if not (official / "src" / "model" / "uplvsm.py").is_file():
        sys.exit(f"--official {official}: no src/model/uplvsm.py (expected a checkout of ou524u/Less3Depend)")
    notes = install_runtime_patches(use_sdpa)
    sys.path.insert(0, str(official))
    import torch
    try:
        import einops  # noqa: F401
    except ImportError:
        sys.exit("einops is not importable: install it or pass --shims DIR holding a stand-in (see --help)")
    ptlvsm = importlib.import_module("src.model.ptlvsm")
    uplvsm = importlib.import_module("src.model.uplvsm")

    def dino_tokenizer_init(self, dino_qknorm=False):
        torch.nn.Module.__init__(self)
        self.dino_vit = ptlvsm.vit_base(img_size=518, patch_size=14, num_register_tokens=4,
                                        interpolate_antialias=True, interpolate_offset=0.0, block_chunks=0,
                                        init_values=1.0, qk_norm=dino_qknorm)
        if hasattr(self.dino_vit, "mask_token"):
            del self.dino_vit.mask_token

    ptlvsm.dino_tokenizer.__init__ = dino_tokenizer_init
    notes.append("dino_tokenizer: official constructor arguments, random init, no pretrained download")

    rays_from_c2w = uplvsm.rays_from_c2w

    @functools.wraps(rays_from_c2w)
    def rays_on_c2w_device(c2w, fxfycxcy, h=224, w=224, device=None):
        return rays_from_c2w(c2w, fxfycxcy, h=h, w=w, device=c2w.device)

    uplvsm.rays_from_c2w = rays_on_c2w_device
    notes.append("rays_from_c2w (as uplvsm.py calls it): device=c2w.device")

    config = load_config(config_path)
    notes.append("perceptual/lpips loss weights -> 0 (no VGG19; training-only)")
    torch.manual_seed(seed)
    model = uplvsm.unposedLVSM(config)
    model.eval()
    for line in notes:
        log("patch: " + line)
    return model, config


def make_batch(config, seed):
    import torch
    from easydict import EasyDict as edict
    size = config.model.image_tokenizer.image_size
    views = INPUT_VIEWS + TARGET_VIEWS
    generator = torch.Generator().manual_seed(seed)
    images = torch.rand(1, views, 3, size, size, generator=generator)
    fxfycxcy = torch.tensor([0.9 * size, 0.9 * size, 0.5 * size, 0.5 * size]).expand(1, views, 4).contiguous()
    c2w = torch.eye(4).expand(1, views, 4, 4).contiguous()
    return edict(image=images, fxfycxcy=fxfycxcy, c2w=c2w)


class RenderOnly:
    """forward(images, fxfycxcy, c2w) -> render [b, 3, 3, H, W], the official eval forward."""

    @staticmethod
    def make(model):
        import torch
        from easydict import EasyDict as edict

        class Wrapper(torch.nn.Module):
            def __init__(self):
                super().__init__()
                self.model = model

            def forward(self, image, fxfycxcy, c2w):
                batch = edict(image=image, fxfycxcy=fxfycxcy, c2w=c2w)
                return self.model(batch, has_target_image=True, target_has_input=False).render

        return Wrapper().eval()


def time_forwards(model, batch, warmup, n):
    import torch
    wrapper = RenderOnly.make(model)
    args = (batch.image, batch.fxfycxcy, batch.c2w)
    with torch.no_grad():
        for i in range(warmup):
            t0 = time.perf_counter()
            wrapper(*args)
            log(f"warm-up {i}: {(time.perf_counter() - t0) / TARGET_VIEWS:.4f} s/view")
        times = []
        for i in range(n):
            t0 = time.perf_counter()
            render = wrapper(*args)
            times.append((time.perf_counter() - t0) / TARGET_VIEWS)
            print(f"run {i} {times[-1]:.4f} s/view", flush=True)
    assert tuple(render.shape) == (1, TARGET_VIEWS, 3) + tuple(batch.image.shape[-2:]), render.shape
    print(f"median {statistics.median(times):.4f} s/view", flush=True)
    print(f"mean {statistics.fmean(times):.4f} s/view", flush=True)


def write_io(io_dir, names, tensors, output):
    io_dir.mkdir(parents=True, exist_ok=True)
    meta = {"inputs": [], "output": None}
    for name, t in zip(names, tensors):
        t = t.detach().contiguous().float()
        (io_dir / f"{name}.f32").write_bytes(t.numpy().astype("<f4").tobytes())
        meta["inputs"].append({"name": name, "shape": list(t.shape), "file": f"{name}.f32"})
    output = output.detach().contiguous().float()
    (io_dir / "render.f32").write_bytes(output.numpy().astype("<f4").tobytes())
    meta["output"] = {"name": "render", "shape": list(output.shape), "file": "render.f32"}
    meta["target_views"] = TARGET_VIEWS
    (io_dir / "io.json").write_text(json.dumps(meta, indent=1) + "\n")


def export_onnx(model, batch, path, ort_dir, opset):
    import torch
    path = pathlib.Path(path).resolve()
    # (1) the DINOv2 positional embedding for this grid, once, by the official method
    dino = model.image_tokenizer[1].dino_vit
    size = batch.image.shape[-1]
    n = (size // dino.patch_size) ** 2
    with torch.no_grad():
        pos = dino.interpolate_pos_encoding(torch.zeros(1, n + 1, dino.embed_dim), size, size).detach().clone()

    def cached_pos(x, w, h):
        assert x.shape[1] == n + 1 and w == size and h == size, "export is for one image size"
        return pos.to(x.dtype)

    dino.interpolate_pos_encoding = cached_pos
    # (2) the checkpoint wrapper (a plain call under no_grad)
    import torch.utils.checkpoint as tuc
    tuc.checkpoint = lambda fn, *args, use_reentrant=None, **kwargs: fn(*args, **kwargs)
    # (3) bias-less LayerNorms get an explicit zero bias: torch 1.13 writes the absent bias of LayerNormalization
    # as "", on which ONNX Runtime's SkipLayerNormFusion (optimisation level extended/all) crashes
    zero_biased = 0
    for m in model.modules():
        if isinstance(m, torch.nn.LayerNorm) and m.weight is not None and m.bias is None:
            m.bias = torch.nn.Parameter(torch.zeros_like(m.weight), requires_grad=False)
            zero_biased += 1
    log(f"export: pos-embed interpolated once and reused; torch.utils.checkpoint bypassed; "
        f"{zero_biased} bias-less LayerNorms given a zero bias")

    wrapper = RenderOnly.make(model)
    names = ["images", "fxfycxcy", "c2w"]
    args = (batch.image, batch.fxfycxcy, batch.c2w)
    with torch.no_grad():
        reference = wrapper(*args)
        t0 = time.perf_counter()
        torch.onnx.export(wrapper, args, str(path), opset_version=opset, input_names=names,
                          output_names=["render"], do_constant_folding=True)
    log(f"exported {path} in {time.perf_counter() - t0:.1f} s: {path.stat().st_size / 2**20:.1f} MiB")
    io_dir = pathlib.Path(str(path) + ".io")
    write_io(io_dir, names, args, reference)
    log(f"inputs and torch's output: {io_dir}/")
    try:
        import onnx
        onnx.checker.check_model(str(path))
        graph_inputs = [i.name for i in onnx.load(str(path), load_external_data=False).graph.input]
        log(f"onnx.checker: ok (onnx {onnx.__version__}); graph inputs {graph_inputs}")
    except ImportError:
        log("onnx not installed: checker skipped")
    try:
        import onnxruntime as ort
        options = ort.SessionOptions()
        options.intra_op_num_threads = torch.get_num_threads()
        session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        feeds = {i.name: dict(zip(names, args))[i.name].numpy() for i in session.get_inputs()}
        out = torch.from_numpy(session.run(["render"], feeds)[0])
        print(f"max_abs_diff onnxruntime-python vs torch {(out - reference).abs().max().item():.3e}", flush=True)
    except ImportError:
        if ort_dir:
            cmd = ["node", str(REPO / "bench" / "ort_x224.mjs"), str(path), "--check", "--time", "1",
                   "--warmup", "0", "--ort-dir", str(ort_dir)]
            log("onnxruntime (Python) not installed: " + " ".join(cmd))
            subprocess.run(cmd, check=True)
        else:
            log("onnxruntime (Python) not installed and no --ort-dir: run bench/ort_x224.mjs FILE --check")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    parser.add_argument("--official", required=True, help="checkout of ou524u/Less3Depend")
    parser.add_argument("--shims", help="directory prepended to sys.path (an einops stand-in)")
    parser.add_argument("--config", help="official YAML (default: OFFICIAL/config/uplvsm_x224.yaml)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--no-sdpa", action="store_true",
                        help="xformers stand-in: exact softmax attention even where torch has SDPA")
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--time", type=int, metavar="N", help="time N forwards")
    group.add_argument("--export-onnx", metavar="FILE")
    parser.add_argument("--warmup", type=int, default=1, help="untimed forwards before --time (default 1)")
    parser.add_argument("--opset", type=int, default=17)
    parser.add_argument("--ort-dir", help="npm prefix with onnxruntime-node (for the export's check)")
    args = parser.parse_args()
    if args.shims:
        sys.path.insert(0, str(pathlib.Path(args.shims).resolve()))

    import torch
    torch.set_num_threads(args.threads)
    config_path = args.config or os.path.join(args.official, "config", "uplvsm_x224.yaml")
    env = {k: os.environ.get(k, "(unset)") for k in
           ("OMP_NUM_THREADS", "OMP_WAIT_POLICY", "OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE")}
    log(f"torch {torch.__version__}, {torch.get_num_threads()} threads, {env}")
    t0 = time.perf_counter()
    model, config = build_model(args.official, config_path, args.seed, not args.no_sdpa)
    params = sum(p.numel() for p in model.parameters())
    t = config.model.transformer
    log(f"built {pathlib.Path(config_path).name}: d {t.d}, layers {t.encoder_n_layer}/{t.estimator_n_layer}/"
        f"{t.decoder_n_layer}, {t.n_latent_vectors} latents, {params / 1e6:.1f} M parameters "
        f"({time.perf_counter() - t0:.1f} s)")
    batch = make_batch(config, 0)
    if args.time is not None:
        time_forwards(model, batch, args.warmup, args.time)
    else:
        export_onnx(model, batch, args.export_onnx, args.ort_dir, args.opset)
    return 0


if __name__ == "__main__":
    sys.exit(main())
