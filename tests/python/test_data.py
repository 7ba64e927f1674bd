# uplvsm.data: the RealEstate10K-like fixture read through the Python Dataset (chunks, and the LVSM layout the CLI
# converts them to), in a DataLoader with worker processes, and users' photos.
import subprocess

import pytest
import torch
import torch.utils.data
import uplvsm

from conftest import CLI, FIXTURES, needs_fixtures

ROOT = FIXTURES / "re10k_chunks" / "root"
TEST_KEYS = ["09d9882a954acbf1", "20e408dd375292a1"]  # one chunk, read in index order (by key)


@pytest.fixture(scope="module")
def truth(fixture_pack):
    return uplvsm.io.read_safetensors(str(FIXTURES / "re10k_chunks" / "truth.safetensors"))


@pytest.fixture(scope="module")
def lvsm_root(tmp_path_factory, fixture_pack):
    root = tmp_path_factory.mktemp("lvsm")
    subprocess.run([CLI, "dataset", "convert", "--from", "chunks", "--input", str(ROOT / "test"), "--output",
                    str(root / "test")], check=True, capture_output=True)
    return root


def test_scenes_cameras_and_views_match_the_fixture(truth):
    data = uplvsm.data.Dataset(ROOT, "test", frames=[0, 5, 15], image_size=126)
    assert len(data) == 2 and sorted(data.keys()) == TEST_KEYS and data.layout == "chunks"
    key = "20e408dd375292a1"
    i = data.find(key)
    assert data.num_frames(i) == 16 and data.poses_known(i) and data.find("nope") == -1
    item = data[i]
    assert item["key"] == key and item["frames"].tolist() == [0, 5, 15]
    assert item["images"].shape == (3, 3, 126, 126) and item["images"].dtype == torch.float32
    assert 0 <= item["images"].min() and item["images"].max() <= 1
    assert torch.allclose(item["c2w"], truth[f"{key}.c2w"][[0, 5, 15]], atol=1e-5)
    # 640x360 -> 126 rows (224 wide, rounded to the patch), centred 126x126 crop: fx scales by 126/360.
    assert torch.allclose(item["fxfycxcy"][:, :2], truth[f"{key}.intrinsics_px"][[0, 5, 15], :2] * 126 / 360, rtol=1e-5)
    assert torch.allclose(item["fxfycxcy"][:, 2:], torch.full((3, 2), 63.0))
    assert torch.equal(data[i - len(data)]["images"], item["images"])  # negative index


def test_chunks_to_lvsm_layout_round_trip_keeps_every_pixel(lvsm_root):
    chunks = uplvsm.data.Dataset(ROOT, "test", image_size=64)
    lvsm = uplvsm.data.Dataset(lvsm_root, "test", image_size=64)
    assert lvsm.layout == "lvsm" and sorted(lvsm.keys()) == sorted(chunks.keys())
    for key in chunks.keys():
        a, b = chunks[chunks.find(key)], lvsm[lvsm.find(key)]
        assert len(a["frames"]) == len(b["frames"]) == 16
        assert torch.equal(a["images"], b["images"]), key  # JPEG decoded once, stored as PNG: the same pixels
        assert torch.allclose(a["fxfycxcy"], b["fxfycxcy"], atol=1e-4) and torch.allclose(a["c2w"], b["c2w"], atol=1e-5)


@needs_fixtures
def test_dataloader_with_two_workers():
    data = uplvsm.data.Dataset(ROOT, "train", frames=lambda i, n: [0, n // 2, n - 1], image_size=56)
    serial = [data[i] for i in range(len(data))]
    loader = torch.utils.data.DataLoader(data, batch_size=2, num_workers=2, shuffle=False)
    batches = list(loader)
    assert [len(b["key"]) for b in batches] == [2, 1]
    assert batches[0]["images"].shape == (2, 3, 3, 56, 56)
    images = torch.cat([b["images"] for b in batches])
    assert torch.equal(images, torch.stack([s["images"] for s in serial]))
    assert sum((b["key"] for b in batches), []) == [s["key"] for s in serial]


@needs_fixtures
def test_dataset_errors_name_the_problem(tmp_path):
    with pytest.raises(RuntimeError, match=str(tmp_path / "nowhere")):
        uplvsm.data.Dataset(tmp_path / "nowhere", "test")
    data = uplvsm.data.Dataset(ROOT, "test")
    with pytest.raises(IndexError, match="scene index 2 is out of range for 2 scenes"):
        data[2]
    with pytest.raises(RuntimeError, match="frame 99"):
        data.load_views(0, [0, 99])
    with pytest.raises(ValueError, match="load_views: frames is empty"):
        data.load_views(0, [])
    with pytest.raises(ValueError, match="image_size and patch_size must be > 0"):
        data.load_views(0, [0], image_size=0)


def test_load_photos(tmp_path):
    for name, size in [("a.png", (40, 60)), ("b.png", (40, 60)), ("tall.png", (60, 40))]:
        uplvsm.io.write_png(str(tmp_path / name), torch.rand(3, *size))
    views = uplvsm.data.load_photos([str(tmp_path / "a.png"), str(tmp_path / "b.png")], image_size=28, patch_size=14,
                                    fov=90.0)
    assert views["images"].shape == (2, 3, 28, 28) and views["frames"].tolist() == [0, 1]
    # fov 90: fx = W / 2 of the resized (42 wide) photo, principal point at the centre of the 28x28 crop.
    assert torch.allclose(views["fxfycxcy"], torch.tensor([[21.0, 21.0, 14.0, 14.0]] * 2), atol=1e-4)
    assert torch.equal(views["c2w"], torch.eye(4).expand(2, 4, 4))
    with pytest.raises(ValueError, match=r"field of view must be in \(0, 180\) degrees"):
        uplvsm.data.load_photos([str(tmp_path / "a.png")], fov=180)
    with pytest.raises(RuntimeError, match="missing.jpg"):
        uplvsm.data.load_photos([str(tmp_path / "missing.jpg")])
    with pytest.raises(RuntimeError, match="photos of one scene need the same aspect"):
        uplvsm.data.load_photos([str(tmp_path / "a.png"), str(tmp_path / "tall.png")], square_crop=False)
