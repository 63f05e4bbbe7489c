"""The closed-loop grasp's configuration (datasets_spec/grasp/seed000.yaml), read and checked
before any work: an error names the file, line:column, key, value and what is allowed."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import yaml


class ConfigError(ValueError):
    """A bad grasp configuration: file:line:col: key = value: what is allowed."""


@dataclass
class Fruit:
    name: str
    object: str          # the sensor spec's object that stands for it
    mass_g: float
    mu: float
    mu_spread: float     # mu drawn in mu * [1 - spread, 1 + spread] per trial
    mass_spread: float   # the same for the mass


@dataclass
class Controller:
    kp: float = 2.0            # N of grip per unit of Gamma error, at every estimate
    grip_min_N: float = 0.25
    grip_max_N: float = 3.2
    grip_start_N: float = 0.25
    resolution_N: float = 0.001


@dataclass
class Hold:
    """What both scenes share: the targets, the lift (the table carries the rest of the weight
    until lift_s) and the trial's length."""
    targets: list[float]
    lift_s: float
    duration_s: float


@dataclass
class WeightDrop(Hold):
    fruits: list[str] = field(default_factory=list)
    drop_at_s: float = 2.0
    drop_jitter_s: float = 0.2
    weight_g: float = 50.0
    slack_mm: float = 0.0    # the wire's slack: the weight falls this far before it pulls


@dataclass
class RiceCup(Hold):
    object: str = "cup"
    cup_g: float = 20.0
    mu: float = 0.8
    fill_start_s: float = 2.0
    fill_g_per_s: float = 8.0
    fill_g: float = 150.0


@dataclass
class GraspConfig:
    path: str
    sensor_spec: str           # absolute path of the chromasim spec
    fruits: dict[str, Fruit]
    weight_drop: WeightDrop
    rice_cup: RiceCup
    controller: Controller = field(default_factory=Controller)
    camera_Hz: float = 100.0
    estimator_Hz: float = 50.0
    latency_ms: float = 10.0
    noise: float = 0.0         # the oracle's Gamma noise (standard deviation)
    slip_mm: float = 5.0       # a slide at least this long is a slip event
    lost_mm: float = 20.0      # a slide this long loses the object: the trial ends
    trials: int = 5
    seed: int = 1
    marks: dict[str, str] = field(default_factory=dict)  # object name -> "file:line:col"


class _Reader:
    """Typed access to a composed YAML mapping, with the marks for error messages."""

    def __init__(self, path: str, node, key: str):
        self.path, self.node, self.key = path, node, key
        if not isinstance(node, yaml.MappingNode):
            self.fail(node, key, _text(node), "a mapping")
        self.items = {k.value: (k, v) for k, v in node.value}

    def fail(self, node, key, value, allowed):
        m = node.start_mark
        raise ConfigError(f"{self.path}:{m.line + 1}:{m.column + 1}: {key} = {value}: "
                          f"allowed: {allowed}")

    def check_keys(self, allowed: set[str]):
        for name, (k, _) in self.items.items():
            if name not in allowed:
                self.fail(k, self._sub(name), name, "one of " + ", ".join(sorted(allowed)))

    def _sub(self, name):
        return f"{self.key}.{name}" if self.key else name

    def has(self, name):
        return name in self.items

    def number(self, name, default=None, lo=-math.inf, hi=math.inf, lo_open=False,
               integer=False):
        if name not in self.items:
            if default is None:
                self.fail(self.node, self._sub(name), "(missing)", "a value is required")
            return default
        node = self.items[name][1]
        allowed = (f"{'an integer' if integer else 'a number'} in "
                   f"{'(' if lo_open else '['}{lo:g}, {hi:g}]")
        try:
            value = int(node.value) if integer else float(node.value)
        except (ValueError, TypeError, AttributeError):
            self.fail(node, self._sub(name), _text(node), allowed)
        if not math.isfinite(value) or value < lo or (lo_open and value == lo) or value > hi:
            self.fail(node, self._sub(name), _text(node), allowed)
        return value

    def string(self, name, default=None, choices=None):
        if name not in self.items:
            if default is None:
                self.fail(self.node, self._sub(name), "(missing)", "a value is required")
            return default
        node = self.items[name][1]
        if not isinstance(node, yaml.ScalarNode) or not node.value:
            self.fail(node, self._sub(name), _text(node), "non-empty text")
        if choices is not None and node.value not in choices:
            self.fail(node, self._sub(name), node.value, ", ".join(choices))
        return node.value

    def sub(self, name, optional=False):
        """The mapping at `name`; an empty one when it is optional and left out."""
        if name not in self.items:
            if not optional:
                self.fail(self.node, self._sub(name), "(missing)", "a mapping is required")
            empty = yaml.MappingNode("tag:yaml.org,2002:map", [], self.node.start_mark)
            return _Reader(self.path, empty, self._sub(name))
        return _Reader(self.path, self.items[name][1], self._sub(name))

    def seq(self, name):
        node = self.items[name][1] if name in self.items else None
        if not isinstance(node, yaml.SequenceNode) or not node.value:
            self.fail(node or self.node, self._sub(name), _text(node), "a non-empty list")
        return node.value

    def targets(self, name):
        out = []
        for i, n in enumerate(self.seq(name)):
            try:
                v = float(n.value)
            except (ValueError, TypeError, AttributeError):
                v = math.nan
            if not (0.0 < v < 1.0):
                self.fail(n, f"{self._sub(name)}[{i}]", _text(n), "a target Gamma in (0, 1)")
            out.append(v)
        return out


def _text(node):
    if node is None:
        return "(missing)"
    return node.value if isinstance(node, yaml.ScalarNode) else f"<{node.id}>"


def load(path: str) -> GraspConfig:
    """Reads and checks the configuration at `path` (ConfigError on any bad key or value)."""
    try:
        with open(path, encoding="utf-8") as f:
            root = yaml.compose(f)
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror}") from e
    except yaml.YAMLError as e:
        m = getattr(e, "problem_mark", None)
        where = f"{path}:{m.line + 1}:{m.column + 1}" if m else path
        raise ConfigError(f"{where}: not YAML: {getattr(e, 'problem', e)}") from e
    r = _Reader(path, root, "")
    r.check_keys({"sensor_spec", "camera_Hz", "estimator", "controller", "fruits",
                  "weight_drop", "rice_cup", "slip", "trials", "seed"})
    spec = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)),
                                        r.string("sensor_spec")))
    if not os.path.isfile(spec):
        r.fail(r.items["sensor_spec"][1], "sensor_spec", r.string("sensor_spec"),
               "a chromasim spec file (relative to this file's folder)")
    r.marks = {}
    fruits = _fruits(r)
    est = r.sub("estimator", optional=True)
    est.check_keys({"rate_Hz", "latency_ms", "noise"})
    cup = r.sub("rice_cup")
    cfg = GraspConfig(path=path, sensor_spec=spec, fruits=fruits,
                      weight_drop=_weight_drop(r.sub("weight_drop"), fruits),
                      rice_cup=_rice_cup(cup),
                      controller=_controller(r.sub("controller", optional=True)),
                      camera_Hz=r.number("camera_Hz", 100.0, 1.0, 1000.0),
                      estimator_Hz=est.number("rate_Hz", 50.0, 0.1, 1000.0),
                      latency_ms=est.number("latency_ms", 10.0, 0.0, 1000.0),
                      noise=est.number("noise", 0.0, 0.0, 1.0),
                      trials=r.number("trials", 5, 1, 10000, integer=True),
                      seed=r.number("seed", 1, 0, 2**31 - 1, integer=True))
    _mark(r, cup, "object")
    cfg.marks = r.marks
    slip = r.sub("slip", optional=True)
    slip.check_keys({"event_mm", "lost_mm"})
    cfg.slip_mm = slip.number("event_mm", 5.0, 0.0, 1000.0, lo_open=True)
    cfg.lost_mm = slip.number("lost_mm", 20.0, cfg.slip_mm, 1000.0)
    if cfg.camera_Hz < cfg.estimator_Hz:
        r.fail(est.items.get("rate_Hz", (None, est.node))[1], "estimator.rate_Hz",
               f"{cfg.estimator_Hz:g}", f"at most camera_Hz ({cfg.camera_Hz:g})")
    return cfg


def _mark(root: _Reader, r: _Reader, key: str) -> None:
    """Records where the object named by `key` is given, for errors found later (an object the
    sensor spec lacks)."""
    node = r.items[key][1]
    m = node.start_mark
    root.marks[node.value] = f"{r.path}:{m.line + 1}:{m.column + 1}: {r._sub(key)}"


def _fruits(r: _Reader) -> dict[str, Fruit]:
    fruits = {}
    for i, node in enumerate(r.seq("fruits")):
        f = _Reader(r.path, node, f"fruits[{i}]")
        f.check_keys({"name", "object", "mass_g", "mu", "mu_spread", "mass_spread"})
        name = f.string("name")
        if name in fruits:
            f.fail(f.items["name"][1], f"fruits[{i}].name", name, "a name used once")
        _mark(r, f, "object" if f.has("object") else "name")
        fruits[name] = Fruit(name, f.string("object", name), f.number("mass_g", None, 0, 5000,
                                                                      lo_open=True),
                             f.number("mu", None, 0.0, 5.0, lo_open=True),
                             f.number("mu_spread", 0.0, 0.0, 0.9),
                             f.number("mass_spread", 0.0, 0.0, 0.9))
    return fruits


def _hold(r: _Reader, duration_s: float) -> dict:
    return dict(targets=r.targets("targets"), lift_s=r.number("lift_s", 0.5, 0.0, 100.0),
                duration_s=r.number("duration_s", duration_s, 0.0, 3600.0, lo_open=True))


def _weight_drop(w: _Reader, fruits) -> WeightDrop:
    w.check_keys({"fruits", "targets", "lift_s", "drop_at_s", "drop_jitter_s", "weight_g",
                  "slack_mm", "duration_s"})
    names = []
    for i, n in enumerate(w.seq("fruits")):
        if n.value not in fruits:
            w.fail(n, f"weight_drop.fruits[{i}]", _text(n), ", ".join(fruits))
        names.append(n.value)
    d = WeightDrop(**_hold(w, 3.5), fruits=names,
                   drop_at_s=w.number("drop_at_s", 2.0, 0.0, 1000.0),
                   drop_jitter_s=w.number("drop_jitter_s", 0.2, 0.0, 100.0),
                   weight_g=w.number("weight_g", 50.0, 0.0, 5000.0),
                   slack_mm=w.number("slack_mm", 0.0, 0.0, 1000.0))
    if d.drop_at_s - d.drop_jitter_s < d.lift_s or d.drop_at_s + d.drop_jitter_s >= d.duration_s:
        w.fail(w.items.get("drop_at_s", (None, w.node))[1], "weight_drop.drop_at_s",
               f"{d.drop_at_s:g}", "drop_at_s -/+ drop_jitter_s between lift_s and duration_s")
    return d


def _rice_cup(c: _Reader) -> RiceCup:
    c.check_keys({"object", "cup_g", "mu", "targets", "lift_s", "fill_start_s", "fill_g_per_s",
                  "fill_g", "duration_s"})
    return RiceCup(**_hold(c, 24.0), object=c.string("object"),
                   cup_g=c.number("cup_g", None, 0.0, 5000.0, lo_open=True),
                   mu=c.number("mu", None, 0.0, 5.0, lo_open=True),
                   fill_start_s=c.number("fill_start_s", 2.0, 0.0, 1e3),
                   fill_g_per_s=c.number("fill_g_per_s", 8.0, 0.0, 1e4, lo_open=True),
                   fill_g=c.number("fill_g", 150.0, 0.0, 5000.0))


def _controller(c: _Reader) -> Controller:
    c.check_keys({"kp", "grip_min_N", "grip_max_N", "grip_start_N", "resolution_N"})
    ctl = Controller(c.number("kp", 2.0, 0.0, 100.0, lo_open=True),
                     c.number("grip_min_N", 0.25, 0.0, 100.0, lo_open=True),
                     c.number("grip_max_N", 3.2, 0.0, 100.0, lo_open=True),
                     c.number("grip_start_N", 0.25, 0.0, 100.0, lo_open=True),
                     c.number("resolution_N", 0.001, 0.0, 1.0))
    if not ctl.grip_min_N <= ctl.grip_start_N <= ctl.grip_max_N:
        c.fail(c.node, "controller", f"[{ctl.grip_min_N:g}, {ctl.grip_start_N:g}, "
               f"{ctl.grip_max_N:g}]", "grip_min_N <= grip_start_N <= grip_max_N")
    return ctl
