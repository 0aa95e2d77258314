"""Mechanisms: the registered, parameterised building blocks of the NC interpolator simulation.

A mechanism is a small dataclass whose fields are its parameters, each named with its unit
(`min_block_time_s`, `t1_s`, `override`). A mechanism belongs to one `kind`, which says where in the
chain it acts:

- `limits`:       adjusts per-block limits before planning (feed override, kinematics, block time)
- `corner`:       decides the speed through block junctions (blend arc, junction deviation)
- `interpolator`: turns the prepared blocks into motion over time (look-ahead planner, FIR, CAM)
- `series`:       changes the sampled motion afterwards (jerk filter)
- `feedback`:     turns commanded axis (joint) positions into the reported feedback positions (feedback
                  delay, following lag); the commanded motion and the cycle time stay as they are
- `measurement`:  what a logger does to the channels it records (logger latency); read by the
                  measurement model and by `feedlog diagnose`, never by the simulation itself

Mechanisms are looked up by name in `REGISTRY` (name -> "module:Class"; adding one is one file plus
one line here). A machine profile switches them on or off and sets their parameters with
`[sim.<name>]` tables (`enabled = true/false` plus parameters); `simulate(..., mechanisms=...)`
overrides the profile, which is how a fitting step sets parameters from outside.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from feedlog.errors import ProfileError, SimulationError
from feedlog.profile import MachineProfile
from feedlog.registry import Registry

KINDS = ("limits", "corner", "interpolator", "series", "feedback", "measurement")
MAX_PARAM_S = 3600.0  # a mechanism's time parameter (a dwell, a lag, a period): at most an hour
MIN_OVERRIDE, MAX_OVERRIDE = 0.001, 10.0  # override dials: 0.1 % to 1000 %


def check_override(name: str, override: float) -> None:
    """An override dial's value must lie in MIN_OVERRIDE..MAX_OVERRIDE (a SimulationError naming `name`)."""
    if not MIN_OVERRIDE <= override <= MAX_OVERRIDE:
        raise SimulationError(f"mechanism {name!r}: override must be from {MIN_OVERRIDE:g} to "
                              f"{MAX_OVERRIDE:g} (0.1 % to 1000 %), got {override}")

# name -> "module:Class" (imported on first use). One line per mechanism.
REGISTRY: Registry[type[Mechanism]] = Registry.lazy("sim mechanism", {
    "cam": "feedlog.sim.cam:CamEstimate",
    "lookahead": "feedlog.sim.planner:LookAheadPlanner",
    "fir": "feedlog.sim.fir:FirInterpolator",
    "blend_arc": "feedlog.sim.corner_blend:BlendArcCorner",
    "junction_deviation": "feedlog.sim.corner_junction:JunctionDeviationCorner",
    "trunnion": "feedlog.sim.kinematics:TrunnionKinematics",
    "naive_cam": "feedlog.sim.naive_cam:NaiveCamMerge",
    "feed_override": "feedlog.sim.feed_override:FeedOverride",
    "rapid_override": "feedlog.sim.rapid_override:RapidOverride",
    "block_time": "feedlog.sim.block_time:BlockTimeFloor",
    "reversal_dwell": "feedlog.sim.reversal_dwell:ReversalDwell",
    "tool_change": "feedlog.sim.tool_change:ToolChangeTime",
    "following_lag": "feedlog.sim.following_lag:FollowingLag",
    "feedback_delay": "feedlog.sim.feedback_delay:FeedbackDelay",
    "axis_scale": "feedlog.sim.axis_scale:AxisScale",
    "backlash": "feedlog.sim.backlash:Backlash",
    "logger_latency": "feedlog.sim.logger_latency:LoggerLatency",
    "jerk_filter": "feedlog.sim.jerk_filter:JerkFilter",
}, error=SimulationError, sort_known=True)

@dataclass
class Mechanism:
    """Base class. Subclasses are dataclasses whose fields are unit-named parameters."""

    name: ClassVar[str] = ""
    kind: ClassVar[str] = ""
    order: ClassVar[int] = 50  # position among mechanisms of the same kind (low runs first)
    uses_corner_law: ClassVar[bool] = True  # interpolators: whether corner laws run before them
    signed_times: ClassVar[tuple[str, ...]] = ()  # `*_s` parameters that may be negative (time offsets)
    # windowed simulation (feedlog.sim.window): `windowed` says the mechanism gives a window's rows the
    # result it gives them in the whole program (ctx.window); an interpolator names its windowed form in
    # `stream` ("module:Class"). `feedback` and `measurement` mechanisms never change the motion.
    windowed: ClassVar[bool] = False
    stream: ClassVar[str] = ""

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        """Whether the mechanism runs when the profile says nothing about it."""
        return False

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict[str, Any]:
        """Parameter defaults derived from the profile (override to read profile fields)."""
        return {}

    @classmethod
    def check_params(cls, profile: MachineProfile, params: Mapping[str, Any]) -> dict[str, Any]:
        """`params` (without `enabled`) if every name is a parameter and every value has its type."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(params) - names - {"enabled"})
        if unknown:
            raise SimulationError(f"mechanism {cls.name!r}: unknown parameter(s) {', '.join(unknown)}; "
                                  f"known: {', '.join(sorted(names)) or 'none'}")
        if "enabled" in params and not isinstance(params["enabled"], bool):
            raise SimulationError(f"mechanism {cls.name!r}: enabled must be true or false, got {params['enabled']!r}")
        defaults = {f.name: f.default if f.default is not dataclasses.MISSING else f.default_factory()
                    for f in dataclasses.fields(cls) if f.init}
        defaults.update(cls.defaults(profile))
        return {k: _checked(cls.name, k, v, defaults.get(k), signed=k in cls.signed_times)
                for k, v in params.items() if k != "enabled"}

    @classmethod
    def from_params(cls, profile: MachineProfile, params: Mapping[str, Any]) -> Mechanism:
        given = cls.check_params(profile, params)
        try:
            return cls(**{**cls.defaults(profile), **given})
        except (TypeError, ValueError) as exc:
            raise SimulationError(f"mechanism {cls.name!r}: {exc}") from None

    # hooks, called by feedlog.sim.simulate in chain order; the defaults do nothing
    def limit(self, ctx) -> None:
        """Adjust `ctx.blocks` (feed, limits, stops, holds) before the path is built."""

    def corner(self, ctx) -> None:
        """Set junction speeds / insert blend pieces in `ctx.pieces` (corner laws)."""

    def run(self, ctx):
        """Interpolate: return a `Trajectory` (interpolators only)."""
        raise NotImplementedError(f"mechanism {self.name!r} is not an interpolator")

    def after(self, ctx, trajectory):
        """Change the sampled trajectory; return the new one."""
        return trajectory

    def feedback(self, dt_s: float, axes: tuple[str, ...], pos: np.ndarray) -> np.ndarray:
        """Feedback positions (n, k) from commanded ones sampled every `dt_s` (feedback mechanisms)."""
        return pos

    def settle_s(self) -> float:
        """Standstill a feedback mechanism needs after the command ends to settle (s)."""
        return 0.0

    def params(self) -> dict[str, Any]:
        """Current parameter values (unit-named), e.g. for writing a fitted profile back."""
        return dataclasses.asdict(self)

    def check_positive(self, **values: float) -> None:
        for key, value in values.items():
            if not value > 0:
                raise SimulationError(f"mechanism {self.name!r}: {key} must be > 0, got {value}")

    def check_non_negative(self, **values: float) -> None:
        for key, value in values.items():
            if not value >= 0:
                raise SimulationError(f"mechanism {self.name!r}: {key} must be >= 0, got {value}")


def _checked(mechanism: str, name: str, value: Any, default: Any, *, signed: bool = False) -> Any:
    """`value` for parameter `name` if it has the type of the parameter's default (numbers finite,
    a list for a tuple of the same length, a table of numbers for a dict; times `*_s` from 0 to an
    hour, or within an hour either way for the mechanism's `signed_times`); SimulationError otherwise."""
    def number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool) and (math.isfinite(v) or v == default)

    low = -MAX_PARAM_S if signed else 0.0
    if name.endswith("_s") and isinstance(default, float) and not (number(value) and low <= value <= MAX_PARAM_S):
        raise SimulationError(f"mechanism {mechanism!r}: parameter {name} must be a time from {low:g} to "
                              f"{MAX_PARAM_S:g} s, got {value!r}")

    if isinstance(default, bool):
        ok, want = isinstance(value, bool), "true or false"
    elif isinstance(default, int):
        ok, want = isinstance(value, int) and not isinstance(value, bool), "a whole number"
    elif isinstance(default, float):
        ok, want = number(value), "a finite number"
    elif isinstance(default, str):
        ok, want = isinstance(value, str), "a string"
    elif isinstance(default, tuple):
        ok, want = isinstance(value, (list, tuple)) and len(value) == len(default) and all(map(number, value)), \
            f"a list of {len(default)} numbers"
        value = tuple(value) if ok else value
    elif isinstance(default, dict):
        ok, want = isinstance(value, dict) and all(isinstance(k, str) and number(v) for k, v in value.items()), \
            "a table of numbers"
    else:
        ok, want = True, ""
    if not ok:
        raise SimulationError(f"mechanism {mechanism!r}: parameter {name} must be {want}, got {value!r}")
    return value


_CLASSES: dict[str, type[Mechanism]] = {}   # found once: a simulation looks every mechanism up each run


def mechanism_class(name: str) -> type[Mechanism]:
    cls = _CLASSES.get(name)
    if cls is None:
        cls = _CLASSES[name] = REGISTRY.get(name)
    return cls


def mechanism_params(profile: MachineProfile | None, name: str) -> dict[str, Any]:
    """The parameters mechanism `name` has under `profile`, switched on or not: its class defaults, those
    it derives from the profile, then the profile's `[sim.<name>]` table; the class defaults alone without
    a profile. How align and train read planner constants the simulation models (one source for all)."""
    cls = mechanism_class(name)
    if profile is None:
        return cls().params()
    return cls.from_params(profile, profile.mechanism(name)).params()


MechanismSpec = Mapping[str, Any] | Sequence[str] | None


def resolve_mechanisms(profile: MachineProfile, mechanisms: MechanismSpec = None) -> list[Mechanism]:
    """The mechanisms that run, in chain order, with their parameters.

    Parameter layers (later wins): class defaults from the profile, the
    profile's `[sim.<name>]` table, then `mechanisms`. `mechanisms` is either a sequence of names
    (exactly those run; the default interpolator is added when none is named) or a mapping
    `name -> {param: value}` / `name -> True/False` applied on top of the profile; switching on an
    interpolator or a corner law there switches off the others of its kind.
    """
    tables: dict[str, dict[str, Any]] = {}
    for name, table in profile.sim.items():
        try:
            if not isinstance(table, Mapping):
                raise SimulationError(f"[sim.{name}] must be a table, got {table!r}")
            mechanism_class(name).check_params(profile, table)  # unknown names and wrong types fail early
        except SimulationError as exc:
            raise ProfileError(f"machine profile {profile.name!r}: {exc}", file=profile.source or None) from None
        tables.setdefault(name, {}).update(table)

    enabled = {name: bool(tables.get(name, {}).get("enabled", mechanism_class(name).default_enabled(profile)))
               for name in REGISTRY}
    if isinstance(mechanisms, Mapping):
        for name, value in mechanisms.items():
            mechanism_class(name)
            if isinstance(value, bool):
                enabled[name] = value
            elif isinstance(value, Mapping):
                tables.setdefault(name, {}).update(value)
                enabled[name] = bool(value.get("enabled", True))
            else:
                raise SimulationError(f"mechanism {name!r}: expected True/False or a parameter mapping, got {value!r}")
        # switching on an interpolator or a corner law switches off the others of its kind
        for kind in ("interpolator", "corner"):
            chosen = [n for n, v in mechanisms.items() if enabled.get(n) and mechanism_class(n).kind == kind
                      and (v is True or isinstance(v, Mapping) and v.get("enabled", True))]
            if chosen:
                for other in REGISTRY:
                    if other not in chosen and mechanism_class(other).kind == kind:
                        enabled[other] = False
    elif mechanisms is not None:
        names = [str(m) for m in mechanisms]
        for name in names:
            mechanism_class(name)
        enabled = {name: name in names for name in REGISTRY}
        if not any(mechanism_class(n).kind == "interpolator" for n in names):
            enabled["fir" if profile.interpolator.fir_t1_s > 0 else "lookahead"] = True

    chain = [mechanism_class(name).from_params(profile, tables.get(name, {}))
             for name, on in enabled.items() if on]
    interpolators = [m for m in chain if m.kind == "interpolator"]
    if len(interpolators) != 1:
        raise SimulationError("exactly one interpolator mechanism must be enabled, got "
                              f"{', '.join(m.name for m in interpolators) or 'none'} (known: cam, lookahead, fir)")
    corners = [m for m in chain if m.kind == "corner"]
    if len(corners) > 1:
        raise SimulationError(f"at most one corner law may be enabled, got {', '.join(m.name for m in corners)}")
    chain.sort(key=lambda m: (KINDS.index(m.kind), m.order, m.name))
    return chain
