# uplvsm.load and uplvsm.Model: the official forward parity through the Python API (the authors' checkpoint.pt of
# the official_uplvsm fixture, random weights), the same frames as the CLI, shared memory, clear errors.
import subprocess

import pytest
import torch
import uplvsm

from conftest import CLI, FIXTURES, OFFICIAL


def max_diff(a, b):
    return torch.max(torch.abs(a - b)).item()


def test_load_reports_the_official_model(official_model):
    m = official_model
    assert m.variant == "uplvsm" and m.parameter_count() == 667047 and m.device == torch.device("cpu")
    t = m.config["model"]["transformer"]
    assert (t["d"], t["encoder_n_layer"], t["decoder_n_layer"], t["n_latent_vectors"]) == (64, 2, 2, 24)
    assert m.config["model"]["image_size"] == 224  # the default for the authors' files (not in the weights)
    assert "uplvsm.Model(variant='uplvsm', parameters=667047" in repr(m)


def test_forward_matches_the_official_code(official_model, official_io):
    f = official_io
    with torch.no_grad():
        out = official_model.forward(f["input.images"], f["input.fxfycxcy"], f["target.images"], f["target.fxfycxcy"])
        assert max_diff(out["render"], f["out.render"]) <= 1e-4
        assert max_diff(out["poses"], f["out.pose_enc"]) <= 1e-4
        # The same through the pieces: scene latents, the Latent Plücker Learner, the decoder.
        latents = official_model.encode_scene(f["input.images"], f["input.fxfycxcy"])
        assert latents.shape == (2, 24, 64) and max_diff(latents, f["inter.latent_tokens"]) <= 1e-4
        poses = official_model.estimate_poses(f["target.images"], latents)
        assert max_diff(poses, f["out.pose_enc"]) <= 1e-4
        render = official_model.render_views(latents, f["out.pose_enc"], f["target.fxfycxcy"], 126, 126)
        assert max_diff(render, f["out.render"]) <= 1e-4
        assert torch.equal(official_model(f["input.images"], f["input.fxfycxcy"], f["target.images"],
                                          f["target.fxfycxcy"])["render"], out["render"])


def test_safetensors_copy_and_gradients(official_model, official_io):
    f = official_io
    copy = uplvsm.load(str(OFFICIAL / "model.safetensors"))
    images = f["input.images"].clone().requires_grad_(True)
    latents = copy.encode_scene(images, f["input.fxfycxcy"])  # grad mode on: autograd reaches the input
    latents.square().sum().backward()
    assert images.grad is not None and images.grad.abs().sum() > 0
    with torch.no_grad():
        assert torch.equal(latents.detach(), official_model.encode_scene(f["input.images"], f["input.fxfycxcy"]))


def test_state_dict_shares_the_models_memory(official_io):
    f = official_io
    m = uplvsm.load(str(OFFICIAL / "checkpoint.pt"))
    a, b = m.state_dict(), m.state_dict()
    assert len(a) >= 93 and all(a[k].data_ptr() == b[k].data_ptr() for k in a)
    weights = uplvsm.io.read_safetensors(str(OFFICIAL / "model.safetensors"))
    assert all(torch.equal(a[k], weights[k]) for k in weights)
    inputs = (f["input.images"], f["input.fxfycxcy"], f["target.images"], f["target.fxfycxcy"])
    with torch.no_grad():
        before = m.forward(*inputs)["render"]
        a["image_token_decoder.1.weight"].mul_(0.5)  # an in-place change in Python is the model's
        after = m.forward(*inputs)["render"]
    assert max_diff(before, after) > 1e-3


def test_render_interpolation_gives_the_clis_frames(tmp_path, official_model, official_io):
    uplvsm.init_runtime()  # the CLI's threads, so both sum in the same order
    for v in range(2):
        uplvsm.io.write_png(str(tmp_path / f"{v}.png"), official_io["input.images"][0, v])
    photos = [str(tmp_path / "0.png"), str(tmp_path / "1.png")]
    subprocess.run([CLI, "render", "--checkpoint", str(OFFICIAL / "checkpoint.pt"), "--images", *photos,
                    "--frames", "6", "--out", str(tmp_path / "cli")], check=True, capture_output=True)
    views = uplvsm.data.load_photos(photos, image_size=official_model.config["model"]["image_size"], fov=60.0)
    video = official_model.render_interpolation(views["images"], views["fxfycxcy"], num_frames=6)
    assert video["frames"].shape == (6, 3, 224, 224) and video["key_poses"].shape == (2, 7)
    assert torch.allclose(video["poses"][[0, -1]], video["key_poses"], atol=1e-6)
    for i, frame in enumerate(video["frames"]):
        cli = uplvsm.io.read_image(str(tmp_path / "cli" / "frames" / f"frame_{i:04d}.png")).permute(2, 0, 1)
        ours = (frame.clamp(0, 1) * 255).round()
        assert (ours - cli.float()).abs().max().item() <= 1, i  # same pixels up to a rounding flip


def test_bad_arguments_raise_clear_errors(official_model, official_io):
    f = official_io
    m = official_model
    with pytest.raises(RuntimeError, match="/nonexistent/model.pt"):
        uplvsm.load("/nonexistent/model.pt")
    with pytest.raises(RuntimeError, match="holds DINOv2 .* weights, not a UP-LVSM model"):
        uplvsm.load(str(FIXTURES / "dinov2" / "weights.pth"))
    with pytest.raises(ValueError, match="expected cpu, cuda, cuda:N or auto, got 'gpu'"):
        uplvsm.load(str(OFFICIAL / "checkpoint.pt"), device="gpu")
    with pytest.raises(ValueError, match="config dict"):
        uplvsm.load(str(OFFICIAL / "checkpoint.pt"), config={"model": {"patch_size": "fourteen"}})
    with pytest.raises(ValueError, match=r"forward: input_fxfycxcy must be \[b, v, 4\] \(\[2, 2\] views\), got \[2, 4\]"):
        m.forward(f["input.images"], f["input.fxfycxcy"][:, 0], f["target.images"], f["target.fxfycxcy"])
    with pytest.raises(ValueError, match="target_poses must be 'auto', 'estimator', 'mapper' or 'dataset', got 'bogus'"):
        m.forward(f["input.images"], f["input.fxfycxcy"], f["target.images"], f["target.fxfycxcy"], target_poses="bogus")
    with pytest.raises(ValueError, match="amp must be 'none' or 'bf16', got 'fp16'"):
        m.encode_scene(f["input.images"], f["input.fxfycxcy"], amp="fp16")
    with pytest.raises(ValueError, match="render_interpolation: images must be two views"):
        m.render_interpolation(f["batch.image"][0], f["batch.fxfycxcy"][0])
    with pytest.raises(RuntimeError, match="needs a camera mapper"):
        m.render_camera_path(f["input.images"][0], f["input.fxfycxcy"][0], torch.zeros(3, 7), torch.ones(3, 4))
    with pytest.raises(RuntimeError, match="needs the input and target c2w|c2w"):
        m.forward(f["input.images"], f["input.fxfycxcy"], f["target.images"], f["target.fxfycxcy"],
                  target_poses="dataset")


def test_init_builds_a_fresh_model_of_a_config():
    from conftest import REPO
    config = REPO / "configs" / "tiny.json"
    a, b = uplvsm.init(str(config), seed=1), uplvsm.init(str(config), seed=1)
    other = uplvsm.init(str(config), seed=2)
    assert a.name == "UP-LVSM" and a.config["name"] == "tiny"
    # The parameter count the CLI reports for the same config (`uplvsm info --config configs/tiny.json`).
    info = subprocess.run([CLI, "info", "--config", str(config)], capture_output=True, text=True, check=True).stdout
    assert f"{a.parameter_count() / 1e6:.2f} M parameters" in info
    sa, sb, so = a.state_dict(), b.state_dict(), other.state_dict()
    assert all(torch.equal(sa[k], sb[k]) for k in sa)  # one seed, one model
    assert not torch.equal(sa["n_light_field_latent"], so["n_light_field_latent"])
    size = 48
    images = torch.rand(1, 3, 3, size, size)
    k = torch.tensor([40.0, 40.0, 24.0, 24.0]).expand(1, 3, 4).contiguous()
    with torch.no_grad():
        out = a.forward(images[:, :2], k[:, :2], images[:, 2:], k[:, 2:])
    assert out["render"].shape == (1, 1, 3, size, size)
    with pytest.raises(ValueError, match="variant"):
        uplvsm.init({"model": {"variant": "nerf"}})
