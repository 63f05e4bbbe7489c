"""A torch Dataset over a chromasim dataset's images and Gamma labels (seed 000's input).

Each item is one frame: the fingertips' PNGs resized to `size` x `size` and stacked
vertically (left on top), 3 x (fingers * size) x size, float in [0, 1], and the frame's
target Gamma (the grasp's, chromasim.data.Dataset.grasp_gamma, unless `target` names one
fingertip). Frames whose solve did not converge (`converged` 0 on any fingertip) are left
out unless `keep_flagged`.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torchvision.io import ImageReadMode, read_image

from .data import Dataset, DatasetError, open_dataset


def stack_fingers(images: list[torch.Tensor], size: int) -> torch.Tensor:
    """The fingertips' uint8 images (3 x H x W each) resized to `size` x `size` and stacked
    vertically in the given order: uint8, 3 x (fingers * size) x size."""
    parts = []
    for img in images:
        if img.shape[1] != size or img.shape[2] != size:
            img = F.interpolate(img[None].float(), size=(size, size),
                                mode="bilinear", antialias=True, align_corners=False)[0]
            img = img.round().clamp(0, 255).to(torch.uint8)
        parts.append(img)
    return torch.cat(parts, dim=1)


class GammaImages(torch.utils.data.Dataset):
    def __init__(self, dataset: Dataset | str, splits: list[str] | None = None,
                 size: int = 224, target: str = "grasp", keep_flagged: bool = False,
                 transform=None, preload: bool = False):
        self.data = open_dataset(dataset) if isinstance(dataset, str) else dataset
        d = self.data
        labels = d.labels
        for f in d.fingers:
            if f"{f}_image" not in labels or not any(labels[f"{f}_image"]):
                raise DatasetError(f"{d.root}: no images (generate with outputs.images: true)")
        rows = np.ones(d.frames, dtype=bool)
        if splits:
            known = sorted(set(labels["split"]))
            for s in splits:
                if s not in known:
                    raise DatasetError(f"{d.root}: no split '{s}' (it has {', '.join(known)})")
            rows &= np.isin(labels["split"], splits)
        if not keep_flagged:
            for f in d.fingers:
                rows &= labels[f"{f}_converged"] == 1
        self.rows = np.flatnonzero(rows)
        if target == "grasp":
            gamma = d.grasp_gamma()
        elif target in d.fingers:
            gamma = labels[f"{target}_gamma"]
        else:
            raise ValueError(f"target {target!r}: allowed grasp, {', '.join(d.fingers)}")
        self.gamma = gamma.astype(np.float32)
        self.size = size
        self.transform = transform
        self._cache: dict[int, torch.Tensor] = {}
        if preload:
            for i in range(len(self.rows)):
                self._cache[i] = self._load(i)

    def __len__(self) -> int:
        return len(self.rows)

    def keys(self) -> np.ndarray:
        """(trial, frame) of every item, shape (len, 2)."""
        return self.data.frame_keys()[self.rows]

    def _load(self, i: int) -> torch.Tensor:
        row = self.rows[i]
        return stack_fingers([
            read_image(self.data.path(self.data.labels[f"{f}_image"][row]), ImageReadMode.RGB)
            for f in self.data.fingers], self.size)

    def __getitem__(self, i: int):
        img = self._cache.get(i)
        if img is None:
            img = self._load(i)
        x = img.float() / 255.0
        if self.transform is not None:
            x = self.transform(x)
        return x, torch.tensor(self.gamma[self.rows[i]]), i
