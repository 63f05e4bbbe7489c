"""Freshly simulated frames for on-the-fly training, without touching disk.

    frames = SimulatedFrames("datasets_spec/seed000_train.yaml", seed=7, size=224)
    loader = torch.utils.data.DataLoader(frames, batch_size=64, num_workers=2,
                                         multiprocessing_context="spawn")

Each item is what chromasim.torch_data.GammaImages gives for the same frame written by
`chromasim generate`: the fingertips' PNG pixels resized to `size` and stacked vertically
(left on top), float in [0, 1], and the grasp's Gamma; flagged frames (a fingertip's solve
did not converge) are left out unless `keep_flagged`. Worker w of n simulates the plan's trials
w, w + n, w + 2n, ... with its own Sensor: the items of a seed are the same whatever the number
of workers, only their order across workers differs. A new `seed` draws a new plan (set one per
epoch for fresh data). Workers must be spawned (multiprocessing_context="spawn" or
"forkserver"): a process forked after the simulator's thread pool started can hang in it.
"""

from __future__ import annotations

import os

import numpy as np
import torch

from .sim import Sensor
from .torch_data import stack_fingers


class SimulatedFrames(torch.utils.data.IterableDataset):
    def __init__(self, spec, *, seed: int | None = None, size: int = 224,
                 target: str = "grasp", keep_flagged: bool = False, cache_dir=None,
                 max_trials: int | None = None, transform=None):
        if target != "grasp" and target not in ("left", "right"):
            raise ValueError(f"target {target!r}: allowed grasp, left, right")
        self.spec = spec if isinstance(spec, dict) else os.fspath(spec)
        self.seed, self.size, self.target = seed, size, target
        self.keep_flagged, self.cache_dir = keep_flagged, cache_dir
        self.max_trials, self.transform = max_trials, transform

    def _worker(self) -> tuple[int, int]:
        info = torch.utils.data.get_worker_info()
        return (0, 1) if info is None else (info.id, info.num_workers)

    def __iter__(self):
        worker, workers = self._worker()
        sensor = Sensor(self.spec, seed=self.seed, cache_dir=self.cache_dir)
        stop = len(sensor) if self.max_trials is None else min(self.max_trials, len(sensor))
        for trial in sensor.trials(worker, stop, workers):
            for frame in trial:
                if not self.keep_flagged and not frame.converged:
                    continue
                x = stack_fingers([torch.from_numpy(np.ascontiguousarray(
                    frame.image(f).transpose(2, 0, 1))) for f in frame.fingers], self.size)
                x = x.float() / 255.0
                if self.transform is not None:
                    x = self.transform(x)
                gamma = frame.gamma if self.target == "grasp" else \
                    frame.labels[f"{self.target}_gamma"]
                yield x, torch.tensor(gamma, dtype=torch.float32), \
                    torch.tensor([frame.trial, frame.index])
