"""The einops stand-in of bench/official_shims (what the official model imports in the benchmark) against explicit
reshape / permute for every pattern the official model uses (bench/official_x224.py --help lists them)."""
import os
import sys

import pytest

torch = pytest.importorskip("torch")
sys.path.insert(0, os.path.join(os.environ.get("UPLVSM_SOURCE_DIR", "."), "bench", "official_shims"))
from einops import rearrange, repeat  # noqa: E402
from einops.layers.torch import Rearrange  # noqa: E402


def test_patchify_and_unpatchify_are_the_explicit_permutes():
    x = torch.randn(2, 3, 4, 6, 10)  # b v c (hh ph) (ww pw), ph = 3, pw = 5
    y = rearrange(x, "b v c (hh ph) (ww pw) -> (b v) (hh ww) (ph pw c)", ph=3, pw=5)
    expected = x.reshape(2, 3, 4, 2, 3, 2, 5).permute(0, 1, 3, 5, 4, 6, 2).reshape(6, 4, 60)
    assert torch.equal(y, expected)
    back = rearrange(y, "(b v) (h w) (p1 p2 c) -> b v c (h p1) (w p2)", b=2, h=2, p1=3, p2=5)
    assert torch.equal(back, x)
    assert torch.equal(Rearrange("b v c h w -> (b v) c h w")(x), x.reshape(6, 4, 6, 10))


def test_heads_and_tokens():
    x = torch.randn(2, 7, 12)
    heads = rearrange(x, "b l (nh dh) -> b l nh dh", nh=3)
    assert torch.equal(heads, x.reshape(2, 7, 3, 4))
    assert torch.equal(rearrange(heads, "b l nh dh -> b l (nh dh)"), x)
    img = rearrange(torch.randn(6, 20, 4), "(b v) (h w) c -> b v c h w", b=2, h=4)
    assert img.shape == (2, 3, 4, 4, 5)
    assert rearrange(torch.randn(6, 5), "(b v) d -> b v d", b=2).shape == (2, 3, 5)


def test_repeat_copies_each_scene_for_its_targets():
    x = torch.randn(2, 5, 7)
    y = repeat(x, "b nl d -> (b v_target) nl d", v_target=3)
    assert y.shape == (6, 5, 7)
    assert torch.equal(y[0], x[0]) and torch.equal(y[2], x[0]) and torch.equal(y[3], x[1])


def test_a_new_axis_in_rearrange_is_an_error():
    with pytest.raises(ValueError):
        rearrange(torch.randn(2, 3), "a b -> a b c")
