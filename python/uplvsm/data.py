"""Datasets and photos as tensors: a torch.utils.data.Dataset over pixelSplat chunks (RealEstate10K / ACID layout)
or the LVSM layout, read in place, and users' own photos."""
import os

import torch.utils.data

from ._uplvsm.data import ChunkDataset, load_photos

__all__ = ["Dataset", "load_photos"]


class Dataset(torch.utils.data.Dataset):
    """One split of a dataset: root/<split> holds pixelSplat chunks (index.json, *.torch) or the LVSM layout
    (full_list.txt, metadata/, images/). Scenes are in the dataset's (chunk) order.

    Item i is a dict: "images" float32 [V, 3, H, W] in [0, 1], "fxfycxcy" [V, 4] pixels, "c2w" [V, 4, 4]
    (OpenCV axes), "frames" int64 [V], "key" str. Which frames: `frames` — a list of frame indices, a callable
    (scene index, number of frames) -> list, or None for every frame of the scene. Works in a DataLoader with
    worker processes (each worker reopens the split; chunks are cached per worker).
    """

    def __init__(self, root, split="test", frames=None, image_size=224, patch_size=14, square_crop=True,
                 cache_chunks=4):
        self.root, self.split = os.fspath(root), split
        self.frames, self.image_size, self.patch_size, self.square_crop = frames, image_size, patch_size, square_crop
        self.cache_chunks = cache_chunks
        self._native = ChunkDataset(self.root, split, cache_chunks)

    def __len__(self):
        return len(self._native)

    def keys(self):
        """Scene keys, in index order."""
        return self._native.keys()

    def find(self, key):
        """Index of the scene with this key, or -1."""
        return self._native.find(key)

    def num_frames(self, i):
        return self._native.num_frames(self._index(i))

    def poses_known(self, i):
        """False for scenes imported without poses (their c2w are placeholders)."""
        return self._native.poses_known(self._index(i))

    @property
    def layout(self):
        """"chunks" or "lvsm"."""
        return self._native.layout

    def load_views(self, i, frames, image_size=None):
        """Frames of scene i (any order, repeats allowed), decoded and preprocessed as the official code does
        (PIL-exact LANCZOS to image_size rows, centred square crop). Raises RuntimeError naming the scene and
        frame for a frame out of range, an undecodable image or a non-finite camera."""
        i = self._index(i)
        size = self.image_size if image_size is None else image_size
        views = self._native.load_views(i, list(frames), size, self.patch_size, self.square_crop)
        views["key"] = self._native.key(i)
        return views

    def __getitem__(self, i):
        i = self._index(i)
        if self.frames is None:
            frames = range(self._native.num_frames(i))
        elif callable(self.frames):
            frames = self.frames(i, self._native.num_frames(i))
        else:
            frames = self.frames
        return self.load_views(i, frames)

    def _index(self, i):
        n = len(self._native)
        if not isinstance(i, int):
            i = int(i)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"scene index {i} is out of range for {n} scenes of {self.root}/{self.split}")
        return i

    # Worker processes started with "spawn" or "forkserver" get the arguments and reopen the split.
    def __getstate__(self):
        state = dict(self.__dict__)
        del state["_native"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._native = ChunkDataset(self.root, self.split, self.cache_chunks)

    def __repr__(self):
        return f"uplvsm.data.Dataset({self.root!r}, split={self.split!r}, scenes={len(self)}, layout={self.layout!r})"
