"""Seed 000's Fig. 5 from a closed-loop grasp run (python3 -m chromasim.grasp):

    python3 -m chromasim.grasp_report out/grasp [--out out/grasp/fig5.png]

A: the grip per fruit and target, held before the weight drop and after it (grey);
B: the probability of a slip per target, one line per fruit;
C: the cup being filled with rice: grip and estimated Gamma over time, one panel per target.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys

import numpy as np


def _read(path: str) -> list[dict]:
    with open(path, encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _panel_a(ax, trials: list[dict]) -> None:
    drops = [t for t in trials if t["scene"] == "weight_drop"]
    fruits = list(dict.fromkeys(t["fruit"] for t in drops))
    targets = sorted({float(t["target"]) for t in drops})
    width = 0.8 / max(1, len(targets))
    colours = ["#4c72b0", "#dd8452", "#55a868", "#c44e52"]
    for j, target in enumerate(targets):
        for i, fruit in enumerate(fruits):
            ts = [t for t in drops if t["fruit"] == fruit and float(t["target"]) == target]
            x = i + (j - (len(targets) - 1) / 2) * width
            for key, shade in (("grip_hold_N", 1.0), ("grip_after_N", 0.45)):
                v = [float(t[key]) for t in ts if t[key] not in ("", "nan")]
                if not v:
                    continue
                off = -width / 4 if key == "grip_hold_N" else width / 4
                bp = ax.boxplot(v, positions=[x + off], widths=width / 2.4, patch_artist=True,
                                showfliers=False, manage_ticks=False)
                bp["boxes"][0].set(facecolor=colours[j % 4] if shade == 1.0 else "0.75",
                                   edgecolor="k")
    from matplotlib.patches import Patch
    handles = [Patch(facecolor=colours[j % 4], edgecolor="k", label=f"target {t:.0%}, held")
               for j, t in enumerate(targets)]
    handles.append(Patch(facecolor="0.75", edgecolor="k", label="after the drop"))
    ax.set_xticks(range(len(fruits)), fruits)
    ax.set_xlim(-0.5, len(fruits) - 0.5)
    ax.set_ylabel("grip force (N)")
    ax.set_title("A  grip per fruit and target")
    ax.legend(handles=handles, fontsize=7)


def _panel_b(ax, summary: list[dict]) -> None:
    drops = [r for r in summary if r["scene"] == "weight_drop"]
    for fruit in dict.fromkeys(r["fruit"] for r in drops):
        rows = sorted((float(r["target"]), float(r["slip_probability"]))
                      for r in drops if r["fruit"] == fruit)
        ax.plot([100 * t for t, _ in rows], [p for _, p in rows], "o-", label=fruit)
    ax.set_xlabel("target safety margin (%)")
    ax.set_ylabel("probability of slip")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title("B  trials with a slip (weight drop)")
    ax.legend(fontsize=7)


def _panel_c(axes, out_dir: str, trials: list[dict]) -> None:
    cups = sorted((t for t in trials if t["scene"] == "rice_cup"), key=lambda t: t["target"])
    for ax, t in zip(axes, cups):
        rows = _read(os.path.join(out_dir, t["trace"]))
        time_s = np.array([float(r["time_s"]) for r in rows])
        ax.plot(time_s, [float(r["grip_N"]) for r in rows], "k", label="grip (N)")
        ax.plot(time_s, [float(r["load_N"]) for r in rows], "0.6", label="load (N)")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("force (N)")
        tw = ax.twinx()
        tw.plot(time_s, [100 * float(r["gamma_est"]) for r in rows], "C3", lw=0.8,
                label="estimated Gamma")
        tw.axhline(100 * float(t["target"]), color="C3", ls=":")
        tw.set_ylim(0, 100)
        tw.set_ylabel("safety margin (%)", color="C3")
        ax.set_title(f"C  rice cup, target {float(t['target']):.0%}")
        ax.legend(loc="upper left", fontsize=7)
    for ax in axes[len(cups):]:
        ax.set_visible(False)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python3 -m chromasim.grasp_report", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", help="a folder written by python3 -m chromasim.grasp")
    p.add_argument("--out", help="the figure (default: RUN/fig5.png)")
    a = p.parse_args(argv)
    try:
        trials = _read(os.path.join(a.run, "trials.csv"))
        summary = _read(os.path.join(a.run, "summary.csv"))
    except OSError as e:
        print(f"chromasim.grasp_report: error: {a.run}: not a finished grasp run "
              f"({e.strerror}: {e.filename})", file=sys.stderr)
        return 2
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    _panel_a(axes[0][0], trials)
    _panel_b(axes[0][1], summary)
    _panel_c(axes[1], a.run, trials)
    fig.tight_layout()
    out = a.out or os.path.join(a.run, "fig5.png")
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
