# uplvsm.io: torch.save files read without Python's unpickler, safetensors, images and video.
import os

import pytest
import torch
import uplvsm

from conftest import FIXTURES, OFFICIAL, needs_fixtures


@needs_fixtures
def test_official_checkpoint_reads_like_torch_load():
    ours = uplvsm.io.read_torch_file(str(OFFICIAL / "checkpoint.pt"))
    theirs = torch.load(str(OFFICIAL / "checkpoint.pt"), map_location="cpu")
    assert list(ours) == list(theirs) == ["model", "optimizer", "lr_scheduler", "fwdbwd_pass_step", "param_update_step"]
    assert list(ours["model"]) == list(theirs["model"]) and len(ours["model"]) == 93
    for name, tensor in theirs["model"].items():
        assert ours["model"][name].dtype == tensor.dtype and torch.equal(ours["model"][name], tensor), name
    assert ours["fwdbwd_pass_step"] == theirs["fwdbwd_pass_step"] == 1
    groups = ours["optimizer"]["param_groups"]
    assert [g["weight_decay"] for g in groups] == [g["weight_decay"] for g in theirs["optimizer"]["param_groups"]]
    assert groups[0]["betas"] == theirs["optimizer"]["param_groups"][0]["betas"]  # a tuple of floats
    state = ours["optimizer"]["state"][0]
    assert torch.equal(state["exp_avg"], theirs["optimizer"]["state"][0]["exp_avg"])


@needs_fixtures
def test_safetensors_and_legacy_torch_files():
    tensors, metadata = uplvsm.io.read_safetensors(str(OFFICIAL / "model.safetensors"), with_metadata=True)
    assert metadata["format"] == "pt" and "random weights" in metadata["source"]
    checkpoint = uplvsm.io.read_torch_file(str(OFFICIAL / "checkpoint.pt"))["model"]
    assert sorted(tensors) == sorted(checkpoint)
    assert all(torch.equal(tensors[k], checkpoint[k]) for k in tensors)
    # The LPIPS lin weights: the legacy (pre-zip) torch.save format.
    lin = uplvsm.io.read_torch_file(str(FIXTURES / "lpips" / "vgg.pth"))
    copy = uplvsm.io.read_safetensors(str(FIXTURES / "lpips" / "lin_vgg.safetensors"))
    assert sorted(lin) == [f"lin{k}.model.1.weight" for k in range(5)]
    assert all(torch.equal(lin[f"lin{k}.model.1.weight"], copy[f"lin{k}"]) for k in range(5))


def test_write_then_read_round_trip(tmp_path):
    tensors = {"a": torch.arange(6, dtype=torch.float32).reshape(2, 3), "b": torch.tensor([1, 2], dtype=torch.int64),
               "c": torch.rand(4, dtype=torch.float64).to(torch.bfloat16)}
    path = str(tmp_path / "t.safetensors")
    uplvsm.io.write_safetensors(path, tensors, {"note": "hello"})
    back, metadata = uplvsm.io.read_safetensors(path, with_metadata=True)
    assert metadata == {"note": "hello"}
    assert all(back[k].dtype == v.dtype and torch.equal(back[k], v) for k, v in tensors.items())


def test_torch_file_values_and_opaque_calls(tmp_path):
    path = str(tmp_path / "obj.pt")
    shared = torch.arange(10, dtype=torch.float32)
    torch.save({"ints": [1, -2, 2**70], "t": (shared[2:5], shared), "s": {"x"}, "b": b"\x00\x01", "none": None,
                "dev": torch.device("cpu")}, path)
    obj = uplvsm.io.read_torch_file(path)
    assert obj["ints"] == [1, -2, 2**70] and obj["s"] == {"x"} and obj["b"] == b"\x00\x01" and obj["none"] is None
    view, whole = obj["t"]
    assert torch.equal(view, shared[2:5]) and whole.data_ptr() == view.data_ptr() - 2 * 4  # one storage, as torch.load
    assert isinstance(obj["dev"], uplvsm.io.OpaqueCall) and obj["dev"].function == "torch.device"
    assert obj["dev"].args == ("cpu",)


def test_hostile_and_broken_files_raise(tmp_path):
    loop = []
    loop.append(loop)
    torch.save(loop, str(tmp_path / "loop.pt"))
    with pytest.raises(ValueError, match="self-referencing"):
        uplvsm.io.read_torch_file(str(tmp_path / "loop.pt"))
    (tmp_path / "junk.pt").write_bytes(b"PK\x03\x04 not a zip at all")
    with pytest.raises(RuntimeError, match="junk.pt"):
        uplvsm.io.read_torch_file(str(tmp_path / "junk.pt"))
    (tmp_path / "short.safetensors").write_bytes(b"\x01\x02")
    with pytest.raises(RuntimeError, match="short.safetensors': file is 2 bytes"):
        uplvsm.io.read_safetensors(str(tmp_path / "short.safetensors"))
    with pytest.raises(RuntimeError, match="missing.safetensors"):
        uplvsm.io.read_safetensors(str(tmp_path / "missing.safetensors"))


def test_images_and_video(tmp_path):
    image = torch.rand(3, 20, 30)
    uplvsm.io.write_png(str(tmp_path / "a.png"), image)
    back = uplvsm.io.read_image(str(tmp_path / "a.png"))
    assert back.dtype == torch.uint8 and back.shape == (20, 30, 3)
    assert torch.equal(back, (image.permute(1, 2, 0) * 255).round().to(torch.uint8))
    with pytest.raises(ValueError, match=r"write_mp4: frames must be float \[F, 3, H, W\]"):
        uplvsm.io.write_mp4(str(tmp_path / "w.mp4"), torch.rand(5, 32, 48), fps=10)
    assert not os.path.exists(tmp_path / "w.mp4")
    try:
        uplvsm.io.write_mp4(str(tmp_path / "v.mp4"), torch.rand(5, 3, 32, 48), fps=10)
    except RuntimeError as e:
        if "without FFmpeg" in str(e):  # -DUPLVSM_WITH_FFMPEG=OFF: a clear error is all there is to check
            pytest.skip(str(e))
        raise
    assert (tmp_path / "v.mp4").read_bytes()[4:8] == b"ftyp"
