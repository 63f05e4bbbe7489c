"""The seeds' figures from a dataset, and error-against-run-time plots from benchmark output.

Usage:
  python3 -m chromasim.figures DATASET -o OUTDIR [--trial N] [--frame F] [--finger left]
                               [--bench FILE ...]
  python3 -m chromasim.figures -o OUTDIR --bench FILE ...        (benchmark plots only)

Figures (PNG and SVG, OUTDIR/<name>.png|svg), each written when the dataset has what it
needs, otherwise skipped with the reason printed:
  force_gamma_trialN          forces and Gamma over one trial (seed 000 Fig. 2E)
  safety_margin_by_friction   Gamma against time or travel per friction condition, mean +- std
                              (seed 001 Fig. 2E)
  markers_<finger>_trialN_frameF     u_z, u_x, u_y of the 82 markers of each layer over the
                              dome's x-y projection (seed 000 Fig. 3C, 3D)
  markers_quiver_<finger>_trialN_frameF  lateral displacement arrows coloured by u_z (Fig. 3D)
  slip_profile_<finger>       the markers of the meridian along the slip direction, deformed
                              (true scale) and their displacements, for the highest- and
                              lowest-friction trials (seed 000 Fig. 3E)
  stickslip_map               stick ratio of every trial over time, per fingertip; full slip
                              marked
  stickslip_trialN            stick ratio, stick and contact area over one trial
  images_trialN               a grid of the trial's tactile images (both fingertips)
  bench_<file>[_k]            error against run time, one per table of a
                              `chromasim bench mechanics|render --json FILE` file
                              (read_bench_json)
docs/PYTHON.md describes the choices.

This module is the command line and the package's figures API; the figures live beside
it: figures_data (what is selected from a dataset: trials, frames, markers, the stick
matrix), figures_plots (the dataset figures) and figures_bench (benchmark tables and their
plots).
"""

from __future__ import annotations

import argparse
import os
import sys

from .data import Dataset, DatasetError, open_dataset  # noqa: F401
# The API of chromasim.figures, re-exported from the modules that implement it
from .figures_bench import (AXIS_LABELS, BENCH_JSON, ERROR_COLUMNS,  # noqa: F401
                            POINT_COLUMNS, SERIES_COLUMNS, TIME_COLUMNS, BenchTable,
                            bench_columns, bench_figures, figure_bench, read_bench_json)
from .figures_data import (RING_POLAR_DEG, Skip, default_frame,  # noqa: F401
                           default_trial, friction_extremes, loaded_frames, marker_ring,
                           meridian, read_markers, slip_direction, stick_matrix, time_axis,
                           trial_rows)
from .figures_data import _select  # noqa: F401  (used by the tests)
from .figures_plots import (PHASE_COLOURS, figure_force_gamma, figure_images,  # noqa: F401
                            figure_marker_maps, figure_marker_quiver,
                            figure_safety_margin_by_friction, figure_slip_profile,
                            figure_stickslip_map, figure_stickslip_trial, nice_gain)


# ---------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python3 -m chromasim.figures",
        description="The seeds' figures from a dataset (seed 000 Fig. 2E, 3C-3E; seed 001 "
                    "Fig. 2E; stick/slip; sample images) and error-against-run-time plots "
                    "from `chromasim bench mechanics|render --json FILE` files. PNG and SVG.")
    p.add_argument("dataset", nargs="?", help="dataset folder written by `chromasim generate`")
    p.add_argument("-o", "--out", required=True, help="output folder (created)")
    p.add_argument("--trial", type=int, default=None,
                   help="trial of the per-trial figures (default: the first that slides)")
    p.add_argument("--frame", type=int, default=None,
                   help="frame of the marker maps (default: per fingertip, the non-sliding "
                        "frame with Gamma closest to 0.5)")
    p.add_argument("--finger", choices=("left", "right"), default=None,
                   help="fingertip of the marker figures (default: every fingertip)")
    p.add_argument("--bench", nargs="+", default=[], metavar="FILE",
                   help="JSON written by `chromasim bench mechanics|render --json FILE`")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not args.dataset and not args.bench:
        sys.exit("figures: give a DATASET and/or --bench FILE ...")
    written, skipped = [], []

    def report(name, why):
        skipped.append(name)
        print(f"figures: skipped {name}: {why}")

    def attempt(name, fn, *a):
        try:
            written.extend(fn(*a))
        except Skip as e:
            report(name, str(e))

    os.makedirs(args.out, exist_ok=True)
    if args.dataset:
        try:
            ds = open_dataset(args.dataset)
            trial = default_trial(ds) if args.trial is None else args.trial
            trial_rows(ds, trial)
        except DatasetError as e:
            sys.exit(f"figures: {_named(e, args.dataset)}")
        _dataset_figures(ds, trial, args, attempt, report)
    for path in args.bench:
        try:
            written.extend(bench_figures(path, args.out, report))
        except DatasetError as e:
            sys.exit(f"figures: --bench {e}")
    for p in written:
        print(f"figures: wrote {p}")
    print(f"figures: {len(written)} files in {args.out}, {len(skipped)} figures skipped")
    return 0 if written else 1


def _dataset_figures(ds, trial, args, attempt, report):
    out = args.out
    fingers = [args.finger] if args.finger else list(ds.fingers)
    attempt("force_gamma", figure_force_gamma, ds, trial, out)
    attempt("safety_margin_by_friction", figure_safety_margin_by_friction, ds, fingers[0], out)
    attempt("stickslip_map", figure_stickslip_map, ds, out)
    attempt("stickslip_trial", figure_stickslip_trial, ds, trial, out)
    attempt("images", figure_images, ds, trial, out)
    try:
        m = read_markers(ds, [trial])
    except Skip as e:
        for f in fingers:
            report(f"markers_{f}", str(e))
            report(f"slip_profile_{f}", str(e))
        return
    for f in fingers:
        frame = default_frame(ds, trial, f) if args.frame is None else args.frame
        attempt(f"markers_{f}", figure_marker_maps, ds, m, trial, frame, f, out)
        attempt(f"markers_quiver_{f}", figure_marker_quiver, ds, m, trial, frame, f, out)
        attempt(f"slip_profile_{f}", figure_slip_profile, ds, f, out)


def _named(error: Exception, path: str) -> str:
    """The error's message, prefixed with the path unless it names the folder already."""
    text = str(error)
    return text if (path in text or os.path.abspath(path) in text) else f"{path}: {text}"


if __name__ == "__main__":
    sys.exit(main())
