# uplvsm.metrics against the reference values of scikit-image (SSIM), the PSNR definition and the official LPIPS.
import json

import pytest
import torch
import uplvsm

from conftest import FIXTURES, needs_fixtures


def ssim_pairs():
    tensors = uplvsm.io.read_safetensors(str(FIXTURES / "ssim_psnr" / "pairs.safetensors"))
    values = json.loads((FIXTURES / "ssim_psnr" / "values.json").read_text())["pairs"]
    return [(tensors[f"pair{v['pair']}.pred"], tensors[f"pair{v['pair']}.gt"], v) for v in values]


@needs_fixtures
def test_psnr_and_ssim_match_the_fixture():
    pairs = ssim_pairs()
    assert len(pairs) == 6
    for pred, gt, ref in pairs:
        assert uplvsm.metrics.psnr(pred, gt).item() == pytest.approx(ref["psnr"], abs=1e-9)
        assert uplvsm.metrics.ssim(pred, gt).item() == pytest.approx(ref["ssim"], abs=1e-6)
        assert uplvsm.metrics.ssim(pred.double(), gt.double()).item() == pytest.approx(ref["ssim_f64"], abs=1e-9)


@needs_fixtures
def test_metrics_take_leading_dimensions():
    pairs = [p for p in ssim_pairs() if list(p[0].shape) == [3, 64, 64]]
    pred = torch.stack([p[0] for p in pairs]).unsqueeze(0)  # [1, 3, 3, 64, 64]
    gt = torch.stack([p[1] for p in pairs]).unsqueeze(0)
    psnr, ssim = uplvsm.metrics.psnr(pred, gt), uplvsm.metrics.ssim(pred, gt)
    assert psnr.shape == (1, 3) and ssim.dtype == torch.float64
    for i, (_, _, ref) in enumerate(pairs):
        assert psnr[0, i].item() == pytest.approx(ref["psnr"], abs=1e-9)
        assert ssim[0, i].item() == pytest.approx(ref["ssim"], abs=1e-6)


@needs_fixtures
@pytest.mark.parametrize("net,backbone", [("vgg", "vgg16_features.safetensors"), ("alex", "alexnet_features.safetensors")])
def test_lpips_matches_the_official_values(net, backbone):
    folder = FIXTURES / "lpips"
    ref = uplvsm.io.read_safetensors(str(folder / "io.safetensors"))
    # The lin weights straight from the official legacy-format .pth (read without Python's unpickler).
    value = uplvsm.metrics.lpips(ref["in0"], ref["in1"], net=net, backbone=folder / backbone, lin=folder / f"{net}.pth")
    assert value.shape == (4,)
    assert torch.max(torch.abs(value - ref[f"{net}.lpips"])).item() <= 1e-5
    metric = uplvsm.metrics.LPIPS(net=net, backbone=str(folder / backbone), lin=str(folder / f"lin_{net}.safetensors"))
    assert torch.max(torch.abs(metric(ref["in0"], ref["in1"]) - ref[f"{net}.lpips"])).item() <= 1e-5
    assert metric.net == net


def test_bad_arguments_raise_clear_errors():
    a, b = torch.rand(3, 16, 16), torch.rand(3, 17, 16)
    with pytest.raises(ValueError, match=r"psnr: pred \[3, 16, 16\] and gt \[3, 17, 16\] differ in shape"):
        uplvsm.metrics.psnr(a, b)
    with pytest.raises(ValueError, match=r"ssim: pred must be \[\.\.\., C, H, W\] of floating point, got Byte"):
        uplvsm.metrics.ssim(torch.zeros(3, 16, 16, dtype=torch.uint8), a)
    with pytest.raises(RuntimeError, match="ssim: images of 8x8"):
        uplvsm.metrics.ssim(torch.rand(3, 8, 8), torch.rand(3, 8, 8))
    with pytest.raises(ValueError, match="LPIPS network 'squeeze': expected 'vgg' or 'alex'"):
        uplvsm.metrics.LPIPS(net="squeeze", backbone="x", lin="y")
    with pytest.raises(RuntimeError, match="/nonexistent/vgg.safetensors"):
        uplvsm.metrics.LPIPS(net="vgg", backbone="/nonexistent/vgg.safetensors", lin=str(FIXTURES / "lpips" / "vgg.pth"))
