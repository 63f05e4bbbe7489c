"""Benchmark tables for chromasim.figures: the JSON of `chromasim bench
mechanics|render --json FILE`, its time and error columns by header name, and one
error-against-run-time plot per table."""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass

import numpy as np

from .data import DatasetError
from .figures_data import Skip


@dataclass
class BenchTable:
    """One table of a `chromasim bench mechanics|render --json FILE` file."""

    caption: str            # the line the Markdown prints before the table ('' if none)
    header: list[str]
    rows: list[list[str]]   # each cell the text the Markdown shows ('' when empty)

    def column(self, j: int) -> np.ndarray:
        return np.array([_number(r[j]) if j < len(r) else np.nan for r in self.rows])


def _number(cell: str) -> float:
    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*%?\s*", cell)
    return float(m.group(1)) if m else np.nan


BENCH_JSON = ("written by `chromasim bench mechanics|render --json FILE`: {command, "
              "chromasim_version, tables: [{caption, header, rows}]}")


def read_bench_json(path: str) -> list[BenchTable]:
    """The tables of a bench's JSON file (BENCH_JSON); a cell that is a number is read as
    its text, null as ''. Raises DatasetError naming the path."""
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except OSError as e:
        raise DatasetError(f"{path}: {e.strerror}") from None
    except ValueError as e:
        raise DatasetError(f"{path}: not JSON ({e}); allowed: a file {BENCH_JSON}") from None
    try:
        tables = doc["tables"]
        if isinstance(tables, list):
            return [_bench_table(t) for t in tables]
    except (KeyError, TypeError, AttributeError):
        pass  # told below
    raise DatasetError(f"{path}: not a bench table file; allowed: a file {BENCH_JSON}")


def _bench_table(t: dict) -> BenchTable:
    header, rows = t["header"], t["rows"]
    if not (isinstance(header, list) and isinstance(rows, list)
            and all(isinstance(r, list) for r in rows)):
        raise TypeError("header and rows are lists")
    return BenchTable(_text(t.get("caption")), [_text(h) for h in header],
                      [[_text(c) for c in r] for r in rows])


def _text(cell) -> str:
    if isinstance(cell, (list, dict)):
        raise TypeError("a cell is text or a number")
    return "" if cell is None else str(cell)


TIME_COLUMNS = ("trial frame ms", "render ms", "frame from rest ms", "frame ms", "time ms",
                "time s", "wall s")
ERROR_COLUMNS = ("rms error", "vs ref", "vs medium", "error")
SERIES_COLUMNS = ("integrator", "mode", "material", "volumetric", "interior")
POINT_COLUMNS = ("spp", "level", "light cache paths per vertex", "size")


def bench_columns(table: BenchTable):
    """(time column, error column, series columns, point-label column) of a table, by
    header names: the time column is the first header starting with one of TIME_COLUMNS
    (in that order of preference), the error column the first containing one of
    ERROR_COLUMNS ('vs ref' is named after the column before it, e.g. indentation mm);
    None when the table has no such pair."""
    low = [h.lower() for h in table.header]

    def first(keys, test):
        for k in keys:
            for j, h in enumerate(low):
                if test(h, k):
                    return j
        return None
    jt = first(TIME_COLUMNS, lambda h, k: h.startswith(k))
    je = first(ERROR_COLUMNS, lambda h, k: k in h and "volume" not in h)
    if jt is None or je is None:
        return None
    series = [j for j, h in enumerate(low) if h in SERIES_COLUMNS]
    point = first(POINT_COLUMNS, lambda h, k: h == k)
    return jt, je, series, point


AXIS_LABELS = {"render ms": "render time per image (ms)",
               "trial frame ms": "time per trial frame (ms)",
               "frame from rest ms (labels)": "time per frame from rest (ms)",
               "rms error %": "RMS error (% of the white level)",
               "less ref noise %": "RMS error less the reference's noise (% of the white level)"}


def _axis_label(header: str, table: BenchTable, j: int) -> str:
    h = header.strip()
    low = h.lower()
    if low in AXIS_LABELS:
        return AXIS_LABELS[low]
    if low.startswith("vs ") and j > 0:
        base = re.sub(r"\s+mm$", "", table.header[j - 1])
        return f"|{base} error {h}| (%)"
    if low.endswith(" ms"):
        return f"{h[:-3]} (ms)"
    if low.endswith(" s"):
        return f"{h[:-2]} (s)"
    if low.endswith("%"):
        return f"{h[:-1].strip()} (% of the white level)" if "error" in low else f"{h[:-1]} (%)"
    return h


def figure_bench(table: BenchTable, stem: str, outdir: str):
    """Error (absolute value, log scale) against time (log scale): one line per series
    (the categorical columns: integrator and mode); with 'vs ref' columns (bench
    mechanics) one line per such column (indentation, apex u_z). Rows of zero error (the
    reference level) are a vertical line at their time."""
    import textwrap

    from .plots import plt, save
    cols = bench_columns(table)
    if cols is None:
        raise Skip("no time and error columns")
    jt, je, series, point = cols
    t = table.column(jt)
    err_cols = [je]
    if table.header[je].lower().startswith("vs "):
        err_cols = [j for j, h in enumerate(table.header) if h == table.header[je]]
    if not any((np.isfinite(t) & np.isfinite(table.column(j))).any() for j in err_cols):
        raise Skip("no row with a number in both the time and the error column")
    fig, ax = plt.subplots(figsize=(6, 4.2), layout="constrained")
    keys = [" ".join(r[j] for j in series if j < len(r)) for r in table.rows]
    refs = set()
    for j in err_cols:
        e = np.abs(table.column(j))
        ok = np.isfinite(t) & np.isfinite(e)
        refs.update(int(i) for i in np.flatnonzero(ok & (e == 0)))
        name = re.sub(r"\s+mm$", "", table.header[j - 1]) if len(err_cols) > 1 else ""
        for key in dict.fromkeys(k for k, o in zip(keys, ok) if o):
            idx = sorted((i for i, (k, o) in enumerate(zip(keys, ok)) if o and k == key
                          and e[i] > 0), key=lambda i: t[i])
            if not idx:
                continue
            ax.plot(t[idx], e[idx], "o-", label=" ".join(x for x in (key, name) if x) or None)
            if point is not None:
                for i in idx:
                    ax.annotate(table.rows[i][point], (t[i], e[i]), textcoords="offset points",
                                xytext=(3, 3), fontsize=7)
    for i in sorted(refs):
        what = table.rows[i][point] if point is not None else f"row {i + 1}"
        ax.axvline(t[i], color="grey", ls=":", lw=1, label=f"reference {what} (0 error)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    _decade_limits(ax)
    ax.set_xlabel(_axis_label(table.header[jt], table, jt))
    ylabel = _axis_label(table.header[je], table, je)
    if len(err_cols) > 1:
        ylabel = f"|error {table.header[je]}| (%)"
    ax.set_ylabel(ylabel)
    cap = textwrap.shorten(table.caption, 300, placeholder=" ...")
    labels = f" (point labels: {table.header[point]})" if point is not None else ""
    ax.set_title("\n".join([f"error against run time{labels}"] + textwrap.wrap(cap, 110)),
                 fontsize=7)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    return save(fig, outdir, stem)


def _decade_limits(ax):
    """Log axes spanning whole decades, tick labels as plain numbers."""
    from matplotlib.ticker import FuncFormatter, NullFormatter
    for axis, get, set_ in ((ax.xaxis, ax.get_xlim, ax.set_xlim),
                            (ax.yaxis, ax.get_ylim, ax.set_ylim)):
        lo, hi = get()
        if lo > 0 and hi > lo:
            set_(10 ** np.floor(np.log10(lo)), 10 ** np.ceil(np.log10(hi)))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_formatter(NullFormatter())


def bench_figures(path: str, outdir: str, report) -> list[str]:
    tables = read_bench_json(path)
    if not tables:
        report(f"bench {path}", "no table in the file")
        return []
    base = re.sub(r"[^A-Za-z0-9_-]+", "_", os.path.splitext(os.path.basename(path))[0])
    stem = base if base.startswith("bench") else f"bench_{base}"
    out = []
    for k, table in enumerate(tables):
        name = stem if len(tables) == 1 else f"{stem}_{k + 1}"
        try:
            out += figure_bench(table, name, outdir)
        except Skip as e:
            report(name, f"table {k + 1} ({' | '.join(table.header[:4])} ...): {e}")
    return out
