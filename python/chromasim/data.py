"""Readers for a dataset folder written by `chromasim generate` (docs/DATASET_FORMAT.md).

Plain numpy: a table is a dict of column name -> 1-D numpy array (float64 for numeric
columns, str for the others), in file order. Nothing here imports torch.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
from dataclasses import dataclass

import numpy as np

FINGERS = ("left", "right")


class DatasetError(ValueError):
    """A dataset folder that is missing a file or holds something this reader cannot use."""


def _table(path: str) -> dict[str, np.ndarray]:
    """Read a CSV with a header row into columns; numeric columns become float64."""
    if not os.path.isfile(path):
        raise DatasetError(f"{path}: no such file")
    with open(path, newline="") as f:
        reader = csv.reader(f)
        try:
            header = next(reader)
        except StopIteration:
            raise DatasetError(f"{path}: empty file, expected a header row") from None
        rows = list(reader)
    for i, row in enumerate(rows):
        if len(row) != len(header):
            raise DatasetError(
                f"{path}:{i + 2}: {len(row)} fields, the header has {len(header)}")
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        values = [row[j] for row in rows]
        try:
            columns[name] = np.array([float(v) if v != "" else np.nan for v in values],
                                     dtype=np.float64)
            if values and all(v == "" for v in values):
                columns[name] = np.array(values, dtype=object)
        except ValueError:
            columns[name] = np.array(values, dtype=object)
    return columns


def read_csv(path: str) -> dict[str, np.ndarray]:
    """Any CSV with a header row (labels, markers, predictions) as columns."""
    return _table(path)


@dataclass
class Dataset:
    """A dataset folder: its manifest and labels, loaded once; markers and strain on demand."""

    root: str
    manifest: dict
    labels: dict[str, np.ndarray]

    @property
    def fingers(self) -> tuple[str, ...]:
        return FINGERS[: int(self.manifest.get("fingers", 1))]

    @property
    def frames(self) -> int:
        return len(self.labels["trial"])

    def path(self, relative: str) -> str:
        return os.path.join(self.root, relative)

    def frame_keys(self) -> np.ndarray:
        """(trial, frame) of every labels row as an int64 array of shape (frames, 2)."""
        return np.stack([self.labels["trial"], self.labels["frame"]], axis=1).astype(np.int64)

    def grasp_gamma(self) -> np.ndarray:
        """The grasp's safety margin per frame, as seed 000 defines it for the whole grasp:
        Gamma = (sum_i mu_i f_n,i - sum_i f_t,i) / sum_i mu_i f_n,i over the fingertips.
        Each fingertip's f_t is taken as the label set states it, mu_i f_n,i (1 - gamma_i),
        so a fingertip labelled sliding (gamma 0) counts at its full strength; the result is
        the strength-weighted mean of the fingertips' `gamma`, in [0, 1], 0 where no
        fingertip has strength. With one fingertip it is that fingertip's `gamma`."""
        strength = np.zeros(self.frames)
        margin = np.zeros(self.frames)
        for finger in self.fingers:
            s = self.labels[f"{finger}_frictional_strength_N"]
            strength += s
            margin += s * self.labels[f"{finger}_gamma"]
        with np.errstate(divide="ignore", invalid="ignore"):
            gamma = np.where(strength > 0, margin / strength, 0.0)
        return np.clip(gamma, 0.0, 1.0)

    def frame_mu(self) -> np.ndarray:
        """The frame's friction coefficient: the mean of its fingertips' mu."""
        return np.mean([self.labels[f"{f}_mu"] for f in self.fingers], axis=0)

    def markers(self) -> dict[str, np.ndarray]:
        """markers.csv as columns (164 rows per fingertip per frame)."""
        return _table(self.path("markers.csv"))

    def frame_sensor(self) -> np.ndarray:
        """The sensor (sensors.csv) that made each labels row, an int64 array; all -1 when
        the spec varies no sensor. Group by it for a leave-one-sensor-out split."""
        if not os.path.exists(self.path("sensors.csv")):
            return np.full(self.frames, -1, dtype=np.int64)
        table = _table(self.path("sensors.csv"))
        of_trial = dict(zip(table["trial"].astype(np.int64), table["sensor"].astype(np.int64)))
        return np.array([of_trial[int(t)] for t in self.labels["trial"]], dtype=np.int64)

    def strain_files(self) -> list[tuple[str, int, str, str]]:
        """(split, trial, finger, path) of every strain file, in trial then finger order."""
        out = []
        for rel in sorted(self.manifest.get("files", {})):
            parts = rel.split("/")
            if len(parts) == 4 and parts[0] == "strain" and parts[3].endswith(".csv"):
                trial = int(parts[2].removeprefix("trial_"))
                out.append((parts[1], trial, parts[3][:-4], self.path(rel)))
        out.sort(key=lambda t: (t[1], FINGERS.index(t[2]) if t[2] in FINGERS else 9))
        return out

    def strain(self, finger: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """All strain fields stacked: (fields, keys) with fields of shape (n, ny * nx)
        (row-major: index iy * nx + ix) and keys (n, 2) = (trial, frame). Only the given
        fingertip's files when `finger` is set. The grid is `strain_grid()`."""
        fields, keys = [], []
        files = [f for f in self.strain_files() if finger is None or f[2] == finger]
        if not files:
            raise DatasetError(f"{self.root}: no strain files (generate with outputs.strain: true)")
        for _, trial, _, path in files:
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
            keys.append(np.stack([np.full(len(data), trial), data[:, 0]], axis=1))
            fields.append(data[:, 1:])
        return np.concatenate(fields), np.concatenate(keys).astype(np.int64)

    def strain_grid(self) -> dict:
        """nx, ny, half_width_x_mm, half_width_y_mm of the strain grid (manifest.json)."""
        grid = self.manifest.get("strain_grid")
        if not grid:
            raise DatasetError(f"{self.root}/manifest.json: no strain_grid (outputs.strain is off)")
        return grid

    def verify(self) -> list[str]:
        """Files whose SHA-256 differs from the manifest's (empty when all match)."""
        bad = []
        for rel, digest in self.manifest.get("files", {}).items():
            h = hashlib.sha256()
            try:
                with open(self.path(rel), "rb") as f:
                    for block in iter(lambda: f.read(1 << 20), b""):
                        h.update(block)
            except OSError:
                bad.append(rel)
                continue
            if h.hexdigest() != digest:
                bad.append(rel)
        return bad


def open_dataset(root: str) -> Dataset:
    """Load a dataset folder's manifest.json and labels.csv (docs/DATASET_FORMAT.md)."""
    root = os.path.abspath(root)
    manifest_path = os.path.join(root, "manifest.json")
    if not os.path.isdir(root):
        raise DatasetError(f"{root}: not a folder (expected the output of `chromasim generate`)")
    if not os.path.isfile(manifest_path):
        hint = " (an interrupted run: finish it with `chromasim generate ... --resume`)" \
            if root.endswith(".partial") else ""
        raise DatasetError(f"{manifest_path}: no such file; not a complete chromasim dataset{hint}")
    with open(manifest_path) as f:
        try:
            manifest = json.load(f)
        except json.JSONDecodeError as e:
            raise DatasetError(f"{manifest_path}:{e.lineno}:{e.colno}: {e.msg}") from None
    if manifest.get("manifest_version") != 1:
        raise DatasetError(f"{manifest_path}: manifest_version {manifest.get('manifest_version')!r},"
                           " this reader knows 1")
    labels = _table(os.path.join(root, "labels.csv"))
    for column in ("split", "trial", "frame", "object", "friction"):
        if column not in labels:
            raise DatasetError(f"{root}/labels.csv: no column '{column}'")
    return Dataset(root=root, manifest=manifest, labels=labels)
