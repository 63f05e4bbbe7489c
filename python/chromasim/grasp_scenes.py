"""The closed-loop grasp's scenes and what is read from a finished trial (chromasim.grasp).

Randomness (docs/GRASP.md): each weight-drop trial draws the fruit's mu and mass uniformly
within their spreads and the drop time within drop_at_s +/- drop_jitter_s, and the oracle's
noise, from a generator seeded by (seed, fruit, target, trial): a trial's result does not
depend on which other trials run.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from .grasp_loop import G, Scene, TrialResult


def trial_rng(seed: int, *key) -> np.random.Generator:
    """A generator for one trial, from the run's seed and the trial's identity."""
    text = "/".join(str(k) for k in key).encode()
    return np.random.default_rng([seed, zlib.crc32(text)])


def _spread(rng: np.random.Generator, value: float, spread: float) -> float:
    return value * (1.0 + rng.uniform(-spread, spread)) if spread > 0 else value


def weight_drop_scene(cfg, fruit_name: str, target: float, trial: int,
                      rng: np.random.Generator) -> Scene:
    """A fruit lifted, held, and a weight dropped on its wire part-way through the hold."""
    wd = cfg.weight_drop
    fruit = cfg.fruits[fruit_name]
    mu = _spread(rng, fruit.mu, fruit.mu_spread)
    mass = _spread(rng, fruit.mass_g, fruit.mass_spread)
    drop = wd.drop_at_s + (rng.uniform(-wd.drop_jitter_s, wd.drop_jitter_s)
                           if wd.drop_jitter_s > 0 else 0.0)
    fall_s = math.sqrt(2.0 * wd.slack_mm / 1000.0 / G)
    catch = drop + fall_s
    w = wd.weight_g
    return Scene(kind="weight_drop", fruit=fruit_name, object=fruit.object, target=target,
                 mu=mu, mass_g=lambda t: mass + (w if t >= catch - 1e-9 else 0.0),
                 lift_s=wd.lift_s, duration_s=wd.duration_s, event_s=drop, trial=trial,
                 catch_s=catch, catch_g=w, catch_v_mm_s=G * fall_s * 1000.0)


def rice_cup_scene(cfg, target: float) -> Scene:
    """A cup lifted, held, and filled with rice at a steady rate."""
    rc = cfg.rice_cup

    def mass(t: float) -> float:
        return rc.cup_g + min(rc.fill_g, max(0.0, t - rc.fill_start_s) * rc.fill_g_per_s)

    return Scene(kind="rice_cup", fruit="cup", object=rc.object, target=target, mu=rc.mu,
                 mass_g=mass, lift_s=rc.lift_s, duration_s=rc.duration_s,
                 event_s=rc.fill_start_s)


@dataclass
class TrialSummary:
    """What a trial shows: its slips, the grip it needed and how fast it reacted."""
    slips: int               # slides of at least slip_mm
    slid_mm: float           # the longest slide
    lost: bool
    grip_hold_N: float       # mean grip over the last 0.5 s before the event
    grip_after_N: float      # mean grip after the event
    grip_max_N: float
    reaction_ms: float       # event -> the first grip command above the hold's (nan: none)
    gamma_hold: float        # mean true Gamma over the last 0.5 s before the event
    gamma_hold_sd: float


def summarize(res: TrialResult, slip_mm: float, rise_N: float = 0.01) -> TrialSummary:
    rows = res.rows
    ev = res.scene.event_s
    hold = [r for r in rows if ev - 0.5 <= r["time_s"] < ev]
    after = [r for r in rows if r["time_s"] >= ev]
    grip_hold = float(np.mean([r["grip_N"] for r in hold])) if hold else math.nan
    gam = np.array([r["gamma_true"] for r in hold]) if hold else np.array([math.nan])
    base = hold[-1]["grip_N"] if hold else math.nan
    reaction = next((1000.0 * (r["time_s"] - ev) for r in after
                     if r["grip_N"] >= base + rise_N), math.nan)
    slides = [s.distance_mm for s in res.slides]
    return TrialSummary(
        slips=max(sum(d >= slip_mm for d in slides), int(res.lost)),
        slid_mm=max(slides, default=0.0), lost=res.lost, grip_hold_N=grip_hold,
        grip_after_N=float(np.mean([r["grip_N"] for r in after])) if after else math.nan,
        grip_max_N=max((r["grip_N"] for r in rows), default=math.nan),
        reaction_ms=reaction, gamma_hold=float(np.mean(gam)),
        gamma_hold_sd=float(np.std(gam)))
