"""The figures of chromasim.eigenstrain, in the style of seed 001's Fig. 4: bases,
recruitments, singular values, accuracy against bases and classes, classification time."""

from __future__ import annotations

import numpy as np

from .eigenstrain_analysis import SCHEME_NAMES, SCHEMES, Eigenstrains
from .eigenstrain_data import StrainSet, grid_axes_mm


def _friction_order(s: StrainSet):
    names = list(dict.fromkeys(s.friction))
    mean_mu = {f: float(np.mean(s.mu[s.friction == f])) for f in names}
    return sorted(names, key=lambda f: mean_mu[f]), mean_mu


def _time_axis(s: StrainSet):
    if np.ptp(s.travel_mm) > 0:
        return s.travel_mm, "relative displacement (travel) (mm)"
    return s.time_s, "time (s)"


def figure_bases(es: Eigenstrains, grid: dict, outdir: str, count: int = 6):
    from .plots import plt, save, symmetric_limit
    x, y = grid_axes_mm(grid)
    count = min(count, len(es.sigma))
    cols = 3 if count > 2 else count
    rows = int(np.ceil(count / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.6 * rows), squeeze=False,
                             layout="constrained")
    frac = es.energy_fraction()
    for i, ax in enumerate(axes.flat):
        if i >= count:
            ax.axis("off")
            continue
        img = es.bases[i].reshape(int(grid["ny"]), int(grid["nx"]))
        lim = symmetric_limit(img)
        im = ax.imshow(img, origin="lower", extent=[x[0], x[-1], y[0], y[-1]],
                       cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="equal")
        ax.set_title(f"u_{i + 1}: sigma^2 {100 * frac[i]:.2f} % of energy")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        fig.colorbar(im, ax=ax, shrink=0.8, label=f"u_{i + 1} (-)")
    fig.suptitle("Eigenstrains: first bases of eps_xx on the strain grid, unit norm "
                 "(red: tension, blue: compression, for a positive recruitment)")
    return save(fig, outdir, "fig4a_bases")


def figure_recruitments(es: Eigenstrains, s: StrainSet, outdir: str, count: int = 6):
    from .plots import plt, save
    t, tlabel = _time_axis(s)
    order, mean_mu = _friction_order(s)
    count = min(count, len(es.sigma))
    cols = 3 if count > 2 else count
    rows = int(np.ceil(count / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.6 * rows), squeeze=False)
    colours = plt.cm.viridis(np.linspace(0, 1, max(len(order), 2)))
    R = es.recruitments(count)
    tk = np.round(t, 9)
    for i, ax in enumerate(axes.flat):
        if i >= count:
            ax.axis("off")
            continue
        for c, f in zip(colours, order):
            m = s.friction == f
            ts = np.unique(tk[m])
            mean = np.array([R[m & (tk == v), i].mean() for v in ts])
            std = np.array([R[m & (tk == v), i].std() for v in ts])
            ax.plot(ts, mean, color=c, lw=1.2, label=f"{f} (mu {mean_mu[f]:.2f})")
            ax.fill_between(ts, mean - std, mean + std, color=c, alpha=0.2, lw=0)
        ax.set_title(f"sigma_{i + 1} v_{i + 1}(t)")
        ax.set_xlabel(tlabel)
        ax.set_ylabel(f"sigma_{i + 1} v_{i + 1} (-)")
    axes.flat[0].legend(fontsize=7, loc="best")
    fig.suptitle("Recruitment of the first bases per friction condition (mean +- std over trials)")
    fig.tight_layout()
    return save(fig, outdir, "fig4a_recruitments")


def _accuracy_band(ax, rows, x_key: str, colour, label: str) -> np.ndarray:
    """Mean accuracy (%) of `rows` against rows[x_key], with a +- std band; returns x."""
    x = np.array([a[x_key] for a in rows])
    m = np.array([a["accuracy_mean"] for a in rows]) * 100
    sd = np.array([a["accuracy_std"] for a in rows]) * 100
    ax.plot(x, m, "o-", color=colour, label=label)
    ax.fill_between(x, m - sd, m + sd, color=colour, alpha=0.2, lw=0)
    return x


def figure_accuracy_vs_bases(acc_rows, outdir: str, classes: int = 2):
    from .plots import plt, save
    fig, ax = plt.subplots(figsize=(5, 3.4))
    chance = None
    for scheme, colour in zip(SCHEMES, ("darkgreen", "yellowgreen")):
        rows = [a for a in acc_rows if a["scheme"] == scheme and a["classes"] == classes]
        rb = sorted((a for a in rows if a["r"] != "full"), key=lambda a: a["r"])
        if not rb:
            continue
        r = _accuracy_band(ax, rb, "r", colour, SCHEME_NAMES[scheme])
        ax.plot(r, [100 * a["balanced_accuracy_mean"] for a in rb], "--", color=colour, lw=1,
                label=f"{SCHEME_NAMES[scheme]}, balanced accuracy")
        full = [a for a in rows if a["r"] == "full"]
        if full:
            ax.errorbar([r.max() + 1.5], [full[0]["accuracy_mean"] * 100],
                        [full[0]["accuracy_std"] * 100], fmt="s", color=colour, capsize=3)
            ax.plot([r.max() + 1.5], [full[0]["balanced_accuracy_mean"] * 100], "x",
                    color=colour)
        chance = rb[0]["chance"]
    if chance is not None:
        ax.axhline(chance * 100, color="grey", ls=":", lw=1, label="majority class")
    ax.set_xlabel("number of bases r")
    ax.set_ylabel("classification rate (%)")
    ax.set_title(f"Gamma in {classes} classes from the first r recruitments "
                 "(square, right: whole strain field)")
    ax.legend(fontsize=7)
    return save(fig, outdir, "fig4b_accuracy_vs_bases")


def figure_accuracy_by_classes(acc_rows, outdir: str, scheme: str = "kfold"):
    from .plots import plt, save
    fig, ax = plt.subplots(figsize=(5, 3.4))
    ks = sorted({a["classes"] for a in acc_rows if a["scheme"] == scheme})
    colours = plt.cm.plasma(np.linspace(0, 0.9, max(len(ks), 2)))
    for k, c in zip(ks, colours):
        rb = sorted((a for a in acc_rows if a["scheme"] == scheme and a["classes"] == k
                     and a["r"] != "full"), key=lambda a: a["r"])
        if rb:
            ax.plot([a["r"] for a in rb], [100 * a["accuracy_mean"] for a in rb], "o-",
                    color=c, ms=3, label=f"{k} classes")
    ax.set_xlabel("number of bases r")
    ax.set_ylabel("classification rate (%)")
    ax.set_title(f"Gamma classes against bases ({SCHEME_NAMES[scheme]})")
    ax.legend(fontsize=7, ncol=2)
    return save(fig, outdir, "accuracy_vs_bases_by_classes")


def figure_accuracy_vs_classes(acc_rows, r: int, conf, conf_k: int, outdir: str):
    from .plots import plt, save
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    ax = axes[0]
    for scheme, colour in zip(SCHEMES, ("darkgreen", "yellowgreen")):
        rb = sorted((a for a in acc_rows if a["scheme"] == scheme and a["r"] == r),
                    key=lambda a: a["classes"])
        if not rb:
            continue
        k = _accuracy_band(ax, rb, "classes", colour, SCHEME_NAMES[scheme])
        ax.plot(k, [100 * a["chance"] for a in rb], ":", color="grey", lw=1)
    ax.set_xlabel("number of classes of Gamma")
    ax.set_ylabel("classification rate (%)")
    ax.set_title(f"{r} bases (dotted: majority class)")
    ax.legend(fontsize=7)
    ax = axes[1]
    if conf is not None:
        rowsum = conf.sum(axis=1, keepdims=True)
        P = np.where(rowsum > 0, conf / np.maximum(rowsum, 1), np.nan) * 100
        im = ax.imshow(P, cmap="Greens", vmin=0, vmax=100, origin="upper")
        edges = np.linspace(0, 1, conf_k + 1)
        ticks = [f"{edges[j]:.1f}-{edges[j + 1]:.1f}" for j in range(conf_k)]
        ax.set_xticks(range(conf_k), ticks, rotation=45, fontsize=7)
        ax.set_yticks(range(conf_k), ticks, fontsize=7)
        for (i, j), n in np.ndenumerate(conf):
            ax.text(j, i, str(n), ha="center", va="center", fontsize=6)
        ax.set_xlabel("predicted Gamma class")
        ax.set_ylabel("true Gamma class")
        ax.set_title(f"confusion, {conf_k} classes, {r} bases, k-fold (% of row; counts)")
        fig.colorbar(im, ax=ax, label="% of the true class")
    else:
        ax.axis("off")
    fig.tight_layout()
    return save(fig, outdir, "fig4d_accuracy_vs_classes")


def figure_time_ratio(timing_rows, outdir: str):
    from .plots import plt, save
    rb = [t for t in timing_rows if t["r"] != "full" and "full_over_r_predict" in t]
    if not rb:
        return []
    fig, ax = plt.subplots(figsize=(5, 3.4))
    r = [t["r"] for t in rb]
    ax.semilogy(r, [1 / t["full_over_r_predict"] for t in rb], "o-",
                label="predict (recruitments given)")
    ax.semilogy(r, [1 / t["full_over_r_project_predict"] for t in rb], "s--",
                label="project on u_i + predict")
    ax.set_xlabel("number of bases r")
    ax.set_ylabel("time with r bases / time with the field (-)")
    ax.set_title("Classification time, 2 classes, against the whole strain field")
    ax.legend(fontsize=7)
    return save(fig, outdir, "fig4c_time_ratio")


def figure_singular_values(es: Eigenstrains, outdir: str):
    from .plots import plt, save
    fig, ax = plt.subplots(figsize=(5, 3.4))
    i = np.arange(1, len(es.sigma) + 1)
    frac = es.energy_fraction()
    ax.semilogy(i, es.sigma, "o-", ms=3, label="sigma_i")
    ax.set_xlabel("basis index i")
    ax.set_ylabel("singular value sigma_i (-)")
    ax2 = ax.twinx()
    ax2.plot(i, 100 * np.cumsum(frac), "r.-", ms=3, label="cumulative energy")
    ax2.set_ylabel("cumulative sum of sigma^2 / ||X||_F^2 (%)", color="r")
    ax.set_title("Singular values of the strain data matrix")
    return save(fig, outdir, "singular_values")
