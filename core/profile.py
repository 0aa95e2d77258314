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
from pathlib import Path
from typing import Any

import tomli_w

from feedlog.errors import ProfileError

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
        if not (self.vel_max > 0 and self.acc_max > 0 and self.jerk_max >= 0):
            raise ProfileError(f"axis {name}: need vel_max > 0, acc_max > 0, jerk_max >= 0, got "
                               f"{self.vel_max}, {self.acc_max}, {self.jerk_max}")
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
        if not (self.servo_period_s > 0 and self.interpolation_period_s > 0):
            raise ProfileError(f"interpolator periods must be > 0, got servo {self.servo_period_s}, "
                               f"interpolation {self.interpolation_period_s}")
        if self.lookahead_blocks < 1:
            raise ProfileError(f"interpolator.lookahead_blocks must be >= 1, got {self.lookahead_blocks}")
        for name in ("fir_t1_s", "fir_t2_s", "block_time_s", "path_tolerance_mm", "orientation_tolerance_deg"):
            if getattr(self, name) < 0:
                raise ProfileError(f"interpolator.{name} must be >= 0, got {getattr(self, name)}")
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

    def __post_init__(self) -> None:
        if not self.axes:
            raise ProfileError(f"profile {self.name!r} has no axes")
        for name, limits in self.axes.items():
            if name not in LINEAR_AXES + ROTARY_AXES:
                raise ProfileError(f"profile {self.name!r}: unknown axis {name!r}")
            limits.check(name)
        if self.rapid_mm_min <= 0:
            raise ProfileError(f"profile {self.name!r}: rapid_mm_min must be > 0, got {self.rapid_mm_min}")
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

        return {
            "name": self.name,
            "controller": self.controller,
            "description": self.description,
            "rapid_mm_min": self.rapid_mm_min,
            "kinematics": clean(dataclasses.asdict(self.kinematics)),
            "interpolator": clean(dataclasses.asdict(self.interpolator)),
            "axes": {k: clean(dataclasses.asdict(v)) for k, v in self.axes.items()},
            "sim": self.sim,
        }

    def to_toml(self) -> str:
        return tomli_w.dumps(self.to_dict())

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<dict>") -> MachineProfile:
        data = dict(data)
        try:
            axes = {k: AxisLimits(**v) for k, v in data.pop("axes", {}).items()}
            kin = data.pop("kinematics", {})
            for key in ("rotary_offset_mm", "workpiece_offset_mm"):
                if key in kin:
                    kin[key] = tuple(float(x) for x in kin[key])
            kinematics = Kinematics(**kin)
            interpolator = Interpolator(**data.pop("interpolator", {}))
            return cls(axes=axes, kinematics=kinematics, interpolator=interpolator, **data)
        except TypeError as exc:  # unknown or missing keys
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


def shipped_profiles() -> list[str]:
    """Short names of the profiles that ship with feedlog."""
    return sorted(p.name[:-5] for p in resources.files("feedlog.profiles").iterdir() if p.name.endswith(".toml"))


def load_profile(name_or_path: str | Path) -> MachineProfile:
    """A shipped profile by short name (`linuxcnc-xyz`) or a profile TOML file by path."""
    text_name = str(name_or_path)
    path = Path(text_name)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ProfileError("machine profile file not found", file=text_name)
        return MachineProfile.from_toml(path.read_text(), source=text_name)
    shipped = resources.files("feedlog.profiles").joinpath(f"{text_name}.toml")
    if not shipped.is_file():
        raise ProfileError(f"unknown machine profile {text_name!r}; shipped: {', '.join(shipped_profiles())} "
                           "(or give a path to a .toml file)")
    return MachineProfile.from_toml(shipped.read_text(), source=f"profile {text_name}")
