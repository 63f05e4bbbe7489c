"""The strain rows of a dataset, with the labels of their frame and fingertip, for
chromasim.eigenstrain: one row per fingertip frame, eps_xx on the ny x nx strain grid
flattened (docs/DATASET_FORMAT.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import Dataset, DatasetError


@dataclass
class StrainSet:
    """The strain rows of a dataset with the labels of their frame and fingertip.

    fields: (n, ny * nx) eps_xx, row-major on the grid (index iy * nx + ix).
    Every other array has n entries."""

    fields: np.ndarray
    trial: np.ndarray
    frame: np.ndarray
    finger: np.ndarray
    friction: np.ndarray
    mu: np.ndarray
    gamma: np.ndarray
    travel_mm: np.ndarray
    time_s: np.ndarray
    grid: dict
    dropped_unconverged: int = 0
    sensor: np.ndarray | None = None   # sensors.csv's sensor of each row's trial (-1: none)

    @property
    def n(self) -> int:
        return len(self.fields)


def load_strain_set(ds: Dataset, finger: str | None = None,
                    drop_unconverged: bool = True, max_travel_mm: float = 0.0) -> StrainSet:
    """Every strain row of `ds` (of one fingertip, or of all that have strain files) with
    its frame's labels. Rows of frames whose fingertip has `converged` 0 are dropped, and
    with max_travel_mm > 0 the rows of frames with travel_mm above it."""
    fingers = [finger] if finger else list(ds.fingers)
    files = {f for _, _, f, _ in ds.strain_files()}
    fingers = [f for f in fingers if f in files]
    if not fingers:
        raise DatasetError(
            f"{ds.root}: no strain files{' for fingertip ' + finger if finger else ''} "
            "(strain/<split>/trial_*/<finger>.csv; generate with outputs.strain: true)")
    grid = ds.strain_grid()
    lab = ds.labels
    row_of = {(int(t), int(f)): i for i, (t, f) in enumerate(ds.frame_keys())}
    parts: dict[str, list] = {k: [] for k in ("fields", "idx", "finger")}
    for fg in fingers:
        fields, keys = ds.strain(fg)
        try:
            idx = np.array([row_of[(int(t), int(f))] for t, f in keys], dtype=np.int64)
        except KeyError as e:
            raise DatasetError(f"{ds.root}: strain row {e.args[0]} (trial, frame) of "
                               f"fingertip {fg} has no labels.csv row") from None
        parts["fields"].append(fields)
        parts["idx"].append(idx)
        parts["finger"].append(np.full(len(idx), fg, dtype=object))
    fields = np.concatenate(parts["fields"])
    idx = np.concatenate(parts["idx"])
    fg = np.concatenate(parts["finger"])
    per_finger = lambda name: np.array(  # noqa: E731
        [lab[f"{f}_{name}"][i] for f, i in zip(fg, idx)], dtype=float)
    keep = np.ones(len(idx), dtype=bool)
    if drop_unconverged and all(f"{f}_converged" in lab for f in fingers):
        keep = per_finger("converged") != 0
    if fields.shape[1] != grid["nx"] * grid["ny"]:
        raise DatasetError(f"{ds.root}: strain rows hold {fields.shape[1]} values, the grid "
                           f"{grid['nx']} x {grid['ny']} needs {grid['nx'] * grid['ny']}")
    if max_travel_mm > 0 and "travel_mm" in lab:
        keep &= lab["travel_mm"][idx] <= max_travel_mm + 1e-9
    s = StrainSet(
        fields=fields, trial=lab["trial"][idx].astype(np.int64),
        frame=lab["frame"][idx].astype(np.int64), finger=fg,
        friction=lab["friction"][idx], mu=per_finger("mu"), gamma=per_finger("gamma"),
        travel_mm=lab["travel_mm"][idx] if "travel_mm" in lab else np.zeros(len(idx)),
        time_s=lab["time_s"][idx], grid=grid, sensor=ds.frame_sensor()[idx])
    if not keep.all():
        for name in ("fields", "trial", "frame", "finger", "friction", "mu", "gamma",
                     "travel_mm", "time_s", "sensor"):
            setattr(s, name, getattr(s, name)[keep])
        s.dropped_unconverged = int((per_finger("converged") == 0).sum()) \
            if drop_unconverged and all(f"{f}_converged" in lab for f in fingers) else 0
    return s


def grid_axes_mm(grid: dict) -> tuple[np.ndarray, np.ndarray]:
    """x (nx) and y (ny) coordinates of the strain grid, mm (docs/DATASET_FORMAT.md)."""
    x = np.linspace(-grid["half_width_x_mm"], grid["half_width_x_mm"], int(grid["nx"]))
    y = np.linspace(-grid["half_width_y_mm"], grid["half_width_y_mm"], int(grid["ny"]))
    return x, y
