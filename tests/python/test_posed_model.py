# uplvsm.load builds either model family through the factory: a posed PT-LVSM run (trained one step here by the CLI)
# loads, renders through forward and render_camera_path, and the UP-LVSM-only methods raise a ValueError naming it.
import subprocess

import pytest
import torch
import uplvsm

from conftest import CLI, REPO


@pytest.fixture(scope="module")
def posed_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("posed")
    configs = REPO / "configs"
    for args in (["make-dataset", "--config", configs / "tiny.json", "--train-scenes", "2", "--test-scenes", "1",
                  "--out", work / "data"],
                 ["train", "--config", configs / "tiny_ptlvsm.json", "--data", work / "data", "--run", work / "run",
                  "--steps", "1"]):
        run = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
        assert run.returncode == 0, run.stdout + run.stderr
    return work


def test_posed_model_renders_and_refuses_the_unposed_methods(posed_run):
    m = uplvsm.load(str(posed_run / "run"))
    assert (m.variant, m.name) == ("ptlvsm", "PT-LVSM") and "variant='ptlvsm'" in repr(m)
    views = uplvsm.data.Dataset(str(posed_run / "data"), "test", image_size=48, patch_size=8).load_views(0, [0, 12, 6])
    images, fxfycxcy, c2w = views["images"], views["fxfycxcy"], views["c2w"]
    with torch.no_grad():
        out = m.forward(images[None, :2], fxfycxcy[None, :2], images[None, 2:], fxfycxcy[None, 2:],
                        input_c2w=c2w[None, :2], target_c2w=c2w[None, 2:])
        assert out["render"].shape == (1, 1, 3, 48, 48) and out["poses"] is None
        path = torch.tensor([[0.0, 0, 0, 0, 0, 0, 1], [0.5, 0, 0, 0, 0, 0, 1]])
        frames = m.render_camera_path(images[:2], fxfycxcy[:2], path, fxfycxcy[:1].expand(2, 4), c2w=c2w[:2])
        assert frames.shape == (2, 3, 48, 48) and not torch.equal(frames[0], frames[1])
        for poses in ("estimator", "mapper"):  # UP-LVSM's latent poses: a posed model has neither
            expected = f"PT-LVSM renders from dataset cameras only; target poses '{poses}'"
            with pytest.raises(RuntimeError, match=expected):
                m.forward(images[None, :2], fxfycxcy[None, :2], images[None, 2:], fxfycxcy[None, 2:],
                          target_poses=poses, input_c2w=c2w[None, :2], target_c2w=c2w[None, 2:])

    latents = torch.zeros(1, 32, 96)
    unposed_only = {
        "encode_scene": lambda: m.encode_scene(images[None, :2], fxfycxcy[None, :2]),
        "estimate_poses": lambda: m.estimate_poses(images[None, 2:], latents),
        "render_views": lambda: m.render_views(latents, torch.zeros(1, 1, 7), fxfycxcy[None, 2:], 48, 48),
        "render_interpolation": lambda: m.render_interpolation(images[:2], fxfycxcy[:2]),
    }
    for name, call in unposed_only.items():
        with pytest.raises(ValueError, match=f"^{name}: only UP-LVSM has scene latents and latent poses; this is a "
                                             "PT-LVSM model .*render_camera_path$"):
            call()
