"""One closed-loop grasp trial (chromasim.grasp): seed 000's P-controller on the estimated
Gamma, the simulator's contact at every camera frame, and the object's fall when the grasp
cannot hold it.

Assumptions (docs/GRASP.md):
- quasi-static contact: every camera frame solves both fingertips' contact under the grip
  and the object's weight, from the last frame (friction history kept); the two fingertips
  squeeze symmetrically, so an estimator that needs no images (the oracle) solves one and
  reads the grasp's Gamma from it;
- the gripper applies each grip command from the next camera frame on (no gripper dynamics),
  rounded to controller.resolution_N;
- the object is rigid and moves only along gravity. It sticks while the fingertips hold its
  weight (the solver reports no sliding or 2 mu f_n exceeds it); otherwise it slides with
  m dv/dt = W - 2 mu f_n (kinetic friction = static), integrated over the camera frame, and
  sticks again when v returns to 0. While it moves each fingertip carries mu f_n (Gamma 0);
- a dropped weight falls freely through the wire's slack, then the taut wire joins it to the
  object in a perfectly inelastic catch: momentum is kept, the object takes the weight's
  share of it, and from then on the weight's mass and weight are the object's;
- the estimator reads the newest camera frame every 1 / rate_Hz and its estimate reaches the
  controller latency_ms later; the controller adds kp (target - estimate) to the grip command.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from .grasp_estimators import EstimatorError, Observation, checked_estimate

G = 9.81
TRACE_COLUMNS = ("time_s", "mass_g", "load_N", "grip_N", "gamma_true", "gamma_est",
                 "estimate", "sliding", "slide_mm", "speed_mm_s")


@dataclass
class Scene:
    """A trial's inputs: `mass_g(t)` (object and what hangs on it), the lift ramp (the table
    carries the rest of the weight before lift_s), mu, the target and the event time."""
    kind: str            # weight_drop | rice_cup
    fruit: str
    object: str
    target: float
    mu: float
    mass_g: object       # callable t -> g
    lift_s: float
    duration_s: float
    event_s: float       # the weight drop's time or the fill's start
    trial: int = 0
    catch_s: float = math.inf   # when the dropped weight's wire goes taut
    catch_g: float = 0.0        # the weight's mass
    catch_v_mm_s: float = 0.0   # its speed then


@dataclass
class Slide:
    start_s: float
    x0_mm: float
    end_s: float | None = None
    distance_mm: float = 0.0


@dataclass
class TrialResult:
    scene: Scene
    rows: list[dict] = field(default_factory=list)
    slides: list[Slide] = field(default_factory=list)
    lost: bool = False
    error: str | None = None
    seconds: float = 0.0
    frames: int = 0
    estimates: int = 0


class _Controller:
    def __init__(self, ctl, target: float):
        self.ctl, self.target = ctl, target
        self.grip = ctl.grip_start_N

    def update(self, estimate: float) -> None:
        c = self.ctl
        grip = self.grip + c.kp * (self.target - estimate)
        grip = min(c.grip_max_N, max(c.grip_min_N, grip))
        if c.resolution_N > 0:
            grip = round(grip / c.resolution_N) * c.resolution_N
        self.grip = grip


class _Object:
    """The object's slide along gravity (mm, mm/s) under W - 2 mu f_n."""

    def __init__(self):
        self.x_mm = 0.0
        self.v_mm_s = 0.0

    @property
    def moving(self) -> bool:
        return self.v_mm_s > 0.0

    def catch(self, mass_g: float, added_g: float, v_mm_s: float) -> None:
        """A perfectly inelastic catch of `added_g` falling at `v_mm_s` by the object."""
        self.v_mm_s = (mass_g * self.v_mm_s + added_g * v_mm_s) / (mass_g + added_g)

    def advance(self, weight_N: float, strength_N: float, mass_kg: float, dt: float) -> None:
        a = (weight_N - strength_N) / mass_kg * 1000.0  # mm/s^2
        v0 = self.v_mm_s
        v1 = max(0.0, v0 + a * dt)
        # time spent moving within the frame when it stops inside it
        t_move = dt if v1 > 0.0 else (v0 / -a if a < 0 else 0.0)
        self.x_mm += 0.5 * (v0 + v1) * min(dt, t_move)
        self.v_mm_s = v1


def run_trial(contact, scene: Scene, estimator, cfg) -> TrialResult:
    """Runs `scene` closed-loop with `estimator` on `contact` (a chromasim Contact, reset here).
    An estimator failure ends the trial with `error` set and the rows so far kept."""
    contact.reset()
    if hasattr(estimator, "reset"):
        estimator.reset()
    res = TrialResult(scene)
    ctl = _Controller(cfg.controller, scene.target)
    obj = _Object()
    dt = 1.0 / cfg.camera_Hz
    every = max(1, round(cfg.camera_Hz / cfg.estimator_Hz))
    pending: list[tuple[float, float]] = []  # (time it reaches the controller, estimate)
    last_est = math.nan
    caught = False
    t0 = time.perf_counter()
    for k in range(int(round(scene.duration_s * cfg.camera_Hz)) + 1):
        t = k * dt
        while pending and pending[0][0] <= t + 1e-9:
            last_est = pending.pop(0)[1]
            ctl.update(last_est)
        if not caught and t >= scene.catch_s - 1e-9:
            caught = True
            obj.catch(scene.mass_g(t) - scene.catch_g, scene.catch_g, scene.catch_v_mm_s)
        frame, row = _frame(contact, scene, obj, ctl.grip, t, dt, res)
        if k % every == 0:
            try:
                est = checked_estimate(estimator, Observation(frame, t))
            except EstimatorError as e:
                res.error = str(e)
                break
            pending.append((t + cfg.latency_ms / 1000.0, est))
            res.estimates += 1
        row.update(gamma_est=last_est, estimate=int(k % every == 0))
        res.rows.append(row)
        res.frames += 1
        if obj.x_mm >= cfg.lost_mm:
            res.lost = True
            break
    res.seconds = time.perf_counter() - t0
    return res


def _frame(contact, scene: Scene, obj: _Object, grip: float, t: float, dt: float,
           res: TrialResult):
    """Solves the fingertips' contact at time `t` and moves the object over the frame."""
    mass_kg = scene.mass_g(t) / 1000.0
    weight = mass_kg * G * (min(1.0, t / scene.lift_s) if scene.lift_s > 0 else 1.0)
    strength = 2.0 * scene.mu * grip
    # a moving object drags each fingertip at its friction limit (kinetic = static friction)
    share = weight / 2.0 if not obj.moving else max(weight / 2.0, scene.mu * grip * 1.001)
    frame = contact.step(grip_N=grip, load_N=share * len(contact.fingers), time_s=t)
    sliding = any(frame.labels[f"{f}_sliding"] for f in contact.fingers)
    if obj.moving or (sliding and weight >= strength):
        if not res.slides or res.slides[-1].end_s is not None:
            res.slides.append(Slide(start_s=t, x0_mm=obj.x_mm))
        obj.advance(weight, strength, mass_kg, dt)
        s = res.slides[-1]
        s.distance_mm = obj.x_mm - s.x0_mm
        if not obj.moving:
            s.end_s = t + dt
    return frame, {"time_s": t, "mass_g": scene.mass_g(t), "load_N": weight, "grip_N": grip,
                   "gamma_true": frame.gamma, "sliding": int(sliding), "slide_mm": obj.x_mm,
                   "speed_mm_s": obj.v_mm_s}
