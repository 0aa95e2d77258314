"""Machine profiles: what the controller is configured with, as a TOML file <-> checked dataclass.

A profile names the axes and their limits, the kinematics, the default path tolerance and the
interpolator's parameters. `sim` holds per-mechanism switches and parameters that feedlog.sim reads
(`[sim.<mechanism>]` tables), so a fitted model can be written back as a profile.

Units: linear axes in mm, mm/s, mm/s^2, mm/s^3; rotary axes in deg, deg/s, deg/s^2, deg/s^3.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

import tomli_w

from feedlog.errors import ProfileError
from feedlog.registry import Registry

def check_number(name: str, value: Any, low: float, high: float, *, integer: bool = False) -> None:
    """A real number (not a bool, a string or NaN) from `low` to `high`; ProfileError otherwise. Bounds
    are far outside any machine: they keep nonsense (1e-300 mm/s, inf) from reaching the simulation."""
    kinds = (int,) if integer else (int, float)
    if isinstance(value, bool) or not isinstance(value, kinds) or not low <= value <= high:
        what = "a whole number" if integer else "a number"
        span = " (inf for no limit)" if math.isinf(low) and math.isinf(high) else f" from {low:g} to {high:g}"
        raise ProfileError(f"{name} must be {what}{span}, got {value!r}")


def _build(cls, table: dict[str, Any], where: str, **extra: Any):
    """`cls(**table)` with unknown and missing keys named (TOML keys are the dataclass fields)."""
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init and f.name != "source"}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        raise ProfileError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(fields)}")
    missing = [name for name, f in fields.items() if name not in table and name not in extra
               and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    if missing:
        raise ProfileError(f"{where}: missing key(s) {', '.join(missing)}")
    return cls(**table, **extra)


LINEAR_AXES = ("x", "y", "z")
ROTARY_AXES = ("a", "b", "c")
KINEMATICS = ("xyz", "xyzac-trt", "xyzbc-trt")


@dataclass(frozen=True)
class AxisLimits:
    """Limits of one axis. `jerk_max` = 0 means the controller does not limit jerk."""

    vel_max: float
    acc_max: float
    jerk_max: float = 0.0
    min_limit: float = -math.inf
    max_limit: float = math.inf

    def check(self, name: str) -> None:
        check_number(f"axis {name}: vel_max", self.vel_max, 1e-3, 1e7)
        check_number(f"axis {name}: acc_max", self.acc_max, 1e-3, 1e9)
        check_number(f"axis {name}: jerk_max", self.jerk_max, 0.0, 1e12)
        for key in ("min_limit", "max_limit"):  # may be unbounded (inf)
            check_number(f"axis {name}: {key}", getattr(self, key), -math.inf, math.inf)
        if not self.min_limit < self.max_limit:
            raise ProfileError(f"axis {name}: min_limit {self.min_limit} must be below max_limit {self.max_limit}")


@dataclass(frozen=True)
class Kinematics:
    """Machine kinematics.

    `xyz`: Cartesian, trivial kinematics. `xyzac-trt`: AC trunnion table (Chien Eq. 7, 10);
    `rotary_offset_mm` is the offset between the A and C rotary axes (LinuxCNC xyzac-trt-kins
    x/y/z-offset), `workpiece_offset_mm` the workpiece origin relative to the rotary centre
    ([Xo, Yo, Zo] in Chien Eq. 10).
    """

    type: str = "xyz"
    rotary_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    workpiece_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_length_mm: float = 0.0

    def check(self) -> None:
        if self.type not in KINEMATICS:
            raise ProfileError(f"unknown kinematics {self.type!r}; known: {', '.join(KINEMATICS)}")
        for name in ("rotary_offset_mm", "workpiece_offset_mm"):
            if len(getattr(self, name)) != 3:
                raise ProfileError(f"kinematics.{name} needs three values, got {getattr(self, name)!r}")
            for value in getattr(self, name):
                check_number(f"kinematics.{name}", value, -1e6, 1e6)
        check_number("kinematics.tool_length_mm", self.tool_length_mm, -1e6, 1e6)

    @property
    def rotary_axes(self) -> tuple[str, ...]:
        return {"xyz": (), "xyzac-trt": ("a", "c"), "xyzbc-trt": ("b", "c")}[self.type]


@dataclass(frozen=True)
class Interpolator:
    """Interpolator parameters (time in seconds)."""

    servo_period_s: float = 0.001
    interpolation_period_s: float = 0.001
    lookahead_blocks: int = 50
    fir_t1_s: float = 0.0
    fir_t2_s: float = 0.0
    block_time_s: float = 0.0
    path_tolerance_mm: float = 0.0
    orientation_tolerance_deg: float = 1.0
    path_vel_max_mm_s: float = math.inf
    path_acc_max_mm_s2: float = math.inf

    def check(self) -> None:
        for name in ("servo_period_s", "interpolation_period_s"):
            check_number(f"interpolator.{name}", getattr(self, name), 1e-6, 1.0)
        check_number("interpolator.lookahead_blocks", self.lookahead_blocks, 1, 100_000, integer=True)
        for name, high in (("fir_t1_s", 10.0), ("fir_t2_s", 10.0), ("block_time_s", 10.0), ("path_tolerance_mm", 1e3),
                           ("orientation_tolerance_deg", 360.0)):
            check_number(f"interpolator.{name}", getattr(self, name), 0.0, high)
        for name in ("path_vel_max_mm_s", "path_acc_max_mm_s2"):  # inf: no path limit
            check_number(f"interpolator.{name}", getattr(self, name), 1e-3, math.inf)
        if self.fir_t2_s > self.fir_t1_s:
            raise ProfileError(f"interpolator.fir_t2_s ({self.fir_t2_s}) must not exceed fir_t1_s ({self.fir_t1_s})")


@dataclass(frozen=True)
class MachineProfile:
    name: str
    axes: dict[str, AxisLimits]
    rapid_mm_min: float
    kinematics: Kinematics = field(default_factory=Kinematics)
    interpolator: Interpolator = field(default_factory=Interpolator)
    controller: str = ""
    description: str = ""
    sim: dict[str, dict[str, Any]] = field(default_factory=dict)
    coverage: dict[str, Any] = field(default_factory=dict)  # what a fitted profile's recordings covered (feedlog.coverage)
    source: str = field(default="", compare=False, repr=False)  # the file it was read from (for messages)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ProfileError(f"profile name must be a string, got {self.name!r}")
        if not self.axes:
            raise ProfileError(f"profile {self.name!r} has no axes")
        for name, limits in self.axes.items():
            if name not in LINEAR_AXES + ROTARY_AXES:
                raise ProfileError(f"profile {self.name!r}: unknown axis {name!r}")
            limits.check(name)
        check_number(f"profile {self.name!r}: rapid_mm_min", self.rapid_mm_min, 1e-3, 1e9)
        if not isinstance(self.sim, dict) or not all(isinstance(t, dict) for t in self.sim.values()):
            raise ProfileError(f"profile {self.name!r}: [sim] must hold one table per mechanism")
        if not isinstance(self.coverage, dict):
            raise ProfileError(f"profile {self.name!r}: [coverage] must be a table")
        from feedlog.coverage import check as check_coverage

        check_coverage(self.coverage, f"profile {self.name!r}")
        self.kinematics.check()
        self.interpolator.check()
        missing = [a for a in LINEAR_AXES + self.kinematics.rotary_axes if a not in self.axes]
        if missing:
            raise ProfileError(f"profile {self.name!r}: kinematics {self.kinematics.type} needs axes "
                               f"{', '.join(missing)}")

    @property
    def axis_names(self) -> tuple[str, ...]:
        return tuple(a for a in LINEAR_AXES + ROTARY_AXES if a in self.axes)

    def mechanism(self, name: str) -> dict[str, Any]:
        """Parameters of one sim mechanism (empty when the profile says nothing about it)."""
        return dict(self.sim.get(name, {}))

    def replace(self, **changes: Any) -> MachineProfile:
        return dataclasses.replace(self, **changes)

    # -- TOML ------------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        def clean(d: dict[str, Any]) -> dict[str, Any]:
            # TOML has no infinity literal that every reader accepts: leave unbounded values out
            return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()
                    if not (isinstance(v, float) and math.isinf(v))}

        out = {
            "name": self.name,
            "controller": self.controller,
            "description": self.description,
            "rapid_mm_min": self.rapid_mm_min,
            "kinematics": clean(dataclasses.asdict(self.kinematics)),
            "interpolator": clean(dataclasses.asdict(self.interpolator)),
            "axes": {k: clean(dataclasses.asdict(v)) for k, v in self.axes.items()},
            "sim": self.sim,
        }
        if self.coverage:  # only fitted profiles carry one
            out["coverage"] = self.coverage
        return out

    def to_toml(self) -> str:
        return tomli_w.dumps(self.to_dict())

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<dict>") -> MachineProfile:
        data = dict(data)
        try:
            tables = {key: data.pop(key, {}) for key in ("axes", "kinematics", "interpolator")}
            bad = [key for key, table in tables.items() if not isinstance(table, dict)]
            bad += [f"axes.{k}" for k, v in tables["axes"].items() if not isinstance(v, dict)] if not bad else []
            if bad:
                raise ProfileError(f"[{bad[0]}] must be a table")
            axes = {k: _build(AxisLimits, v, f"[axes.{k}]") for k, v in tables["axes"].items()}
            kin = dict(tables["kinematics"])
            for key in ("rotary_offset_mm", "workpiece_offset_mm"):
                if key in kin:
                    if not isinstance(kin[key], (list, tuple)):
                        raise ProfileError(f"kinematics.{key} needs three numbers, got {kin[key]!r}")
                    kin[key] = tuple(kin[key])
            kinematics = _build(Kinematics, kin, "[kinematics]")
            interpolator = _build(Interpolator, tables["interpolator"], "[interpolator]")
            return _build(cls, data, "machine profile", axes=axes, kinematics=kinematics, interpolator=interpolator,
                          source=source)
        except TypeError as exc:  # a value of the wrong kind where a comparison needed a number
            raise ProfileError(f"malformed machine profile: {exc}", file=source) from None
        except ProfileError as exc:
            raise ProfileError(exc.message, file=source) from None

    @classmethod
    def from_toml(cls, text: str, *, source: str = "<string>") -> MachineProfile:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ProfileError(f"not valid TOML: {exc}", file=source) from None
        return cls.from_dict(data, source=source)

    def save(self, path: str | Path) -> None:
        Path(path).write_text(self.to_toml())


def path_acc_limit(profile: MachineProfile | None) -> float:
    """The acceleration (mm/s^2) the tool may have along the path: the interpolator's path limit when the
    profile sets one, else the smallest linear axis acceleration; inf without a profile (or linear axes)."""
    if profile is None:
        return math.inf
    acc = profile.interpolator.path_acc_max_mm_s2
    if math.isfinite(acc):
        return float(acc)
    lin = [profile.axes[a].acc_max for a in LINEAR_AXES if a in profile.axes]
    return float(min(lin)) if lin else math.inf


def _find_shipped(registry: Registry[Traversable]) -> None:
    for p in sorted(resources.files("feedlog.profiles").iterdir(), key=lambda p: p.name):
        if p.name.endswith(".toml"):
            registry.add(p.name[:-5], p)


SHIPPED: Registry[Traversable] = Registry("machine profile", error=ProfileError, load=_find_shipped,
                                          known_word="shipped", hint=" (or give a path to a .toml file)")


def shipped_profiles() -> list[str]:
    """Short names of the profiles that ship with feedlog."""
    return SHIPPED.names()


def load_profile(name_or_path: str | Path) -> MachineProfile:
    """A shipped profile by short name (`linuxcnc-xyz`) or a profile TOML file by path."""
    text_name = str(name_or_path)
    path = Path(text_name)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ProfileError("machine profile file not found", file=text_name)
        try:
            text = path.read_bytes().decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise ProfileError(f"not UTF-8 text (byte {exc.start}); TOML files are UTF-8", file=text_name) from None
        except OSError as exc:
            raise ProfileError(f"cannot read the profile: {exc.strerror or exc}", file=text_name) from None
        return MachineProfile.from_toml(text, source=text_name)
    return MachineProfile.from_toml(SHIPPED.get(text_name).read_text(), source=f"profile {text_name}")
