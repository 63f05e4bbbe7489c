"""Matplotlib helpers shared by the figures of chromasim.eigenstrain and chromasim.figures
(eigenstrain_plots, figures_plots, figures_bench).

Agg backend (no display); every figure is saved as PNG and SVG under the same stem.
"""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

plt.rcParams.update({
    "figure.dpi": 100,
    "savefig.dpi": 150,
    "axes.grid": False,
    "font.size": 9,
    "axes.titlesize": 9,
    "svg.fonttype": "none",  # text stays text in the SVG
})

FORMATS = ("png", "svg")


def save(fig, outdir: str, stem: str) -> list[str]:
    """Write `fig` as OUTDIR/STEM.png and OUTDIR/STEM.svg, close it, return the paths."""
    os.makedirs(outdir, exist_ok=True)
    paths = []
    for ext in FORMATS:
        path = os.path.join(outdir, f"{stem}.{ext}")
        fig.savefig(path, bbox_inches="tight")
        paths.append(path)
    plt.close(fig)
    return paths


def symmetric_limit(values, floor: float = 1e-12) -> float:
    """Largest absolute finite value (for a diverging colour map centred on 0)."""
    import numpy as np
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return max(float(np.abs(v).max()) if v.size else 0.0, floor)
