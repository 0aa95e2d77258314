"""What a profile's TOML key is called on the controller: LinuxCNC INI names, Fanuc parameter numbers,
Sinumerik machine data, and a plain-words label for reports.

`names_for(key, controller)` gives the names a machine-tool engineer would look up for `axes.y.acc_max`
(`[AXIS_Y] MAX_ACCELERATION` on LinuxCNC, MD32300 `$MA_MAX_AX_ACCEL` on a Sinumerik). Only names we can
point to in public documentation are listed, each with its source (`SOURCES`):

- LinuxCNC: docs/src/config/ini-config.adoc of the LinuxCNC source ("INI Configuration"), sections
  [EMCMOT], [TRAJ], [AXIS_<letter>], [DISPLAY]. `MAX_JERK` is in the master branch's INI docs, not 2.9's.
- Fanuc: the AI contour control specification A-63512EN (parameter No. 1420, rapid traverse rate for each
  axis). Fanuc's acceleration parameters differ between series and options; none is listed.
- Sinumerik: the SINUMERIK machine data list manuals (840D sl / ONE): MD32000 `$MA_MAX_AX_VELO`,
  MD32300 `$MA_MAX_AX_ACCEL`, MD32431 `$MA_MAX_AX_JERK`, MD36100/36110 `$MA_POS_LIMIT_MINUS/PLUS`.

Fanuc and Sinumerik names are marked "(public docs)" in reports: they are the usual names, to be checked
in the manual of the controller at hand. Which controllers are listed follows the profile's `controller`
text: a LinuxCNC profile gets LinuxCNC's names, a Fanuc or Sinumerik profile its own, any other profile
all of them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

LINUXCNC, FANUC, SINUMERIK = "LinuxCNC", "Fanuc", "Sinumerik"
CONTROLLERS = (LINUXCNC, FANUC, SINUMERIK)
SOURCES = {
    LINUXCNC: "LinuxCNC INI Configuration (docs/src/config/ini-config.adoc)",
    FANUC: "FANUC AI contour control specifications A-63512EN (public docs)",
    SINUMERIK: "SINUMERIK machine data list manual (public docs)",
}


@dataclass(frozen=True)
class ControllerName:
    controller: str
    name: str
    note: str = ""      # a unit or scope the engineer must know (e.g. "ns", "per axis")

    def text(self) -> str:
        parts = [p for p in (self.note, "" if self.controller == LINUXCNC else "public docs") if p]
        note = f" ({', '.join(parts)})" if parts else ""
        label = "LinuxCNC INI" if self.controller == LINUXCNC else self.controller
        return f"{label} `{self.name}`{note}"


# per-axis keys: axes.<letter>.<field> -> the names with {A} for the axis letter
_AXIS: dict[str, tuple[str, list[ControllerName]]] = {
    "vel_max": ("maximum velocity", [ControllerName(LINUXCNC, "[AXIS_{A}] MAX_VELOCITY", "units/s"),
                                     ControllerName(SINUMERIK, "MD32000 $MA_MAX_AX_VELO[{A}]")]),
    "acc_max": ("maximum acceleration", [ControllerName(LINUXCNC, "[AXIS_{A}] MAX_ACCELERATION", "units/s^2"),
                                         ControllerName(SINUMERIK, "MD32300 $MA_MAX_AX_ACCEL[{A}]")]),
    "jerk_max": ("maximum jerk", [ControllerName(LINUXCNC, "[AXIS_{A}] MAX_JERK", "master branch, not 2.9"),
                                  ControllerName(SINUMERIK, "MD32431 $MA_MAX_AX_JERK[{A}]")]),
    "min_limit": ("negative soft limit", [ControllerName(LINUXCNC, "[AXIS_{A}] MIN_LIMIT"),
                                          ControllerName(SINUMERIK, "MD36100 $MA_POS_LIMIT_MINUS[{A}]")]),
    "max_limit": ("positive soft limit", [ControllerName(LINUXCNC, "[AXIS_{A}] MAX_LIMIT"),
                                          ControllerName(SINUMERIK, "MD36110 $MA_POS_LIMIT_PLUS[{A}]")]),
}
_OTHER: dict[str, tuple[str, list[ControllerName]]] = {
    "rapid_mm_min": ("rapid traverse rate", [ControllerName(LINUXCNC, "[AXIS_<L>] MAX_VELOCITY", "rapids run at it"),
                                             ControllerName(FANUC, "No. 1420", "per axis")]),
    "interpolator.servo_period_s": ("servo period", [ControllerName(LINUXCNC, "[EMCMOT] SERVO_PERIOD", "ns")]),
    "interpolator.interpolation_period_s": ("trajectory planner period",
                                            [ControllerName(LINUXCNC, "[EMCMOT] TRAJ_PERIOD", "ns")]),
    "interpolator.path_vel_max_mm_s": ("path velocity limit",
                                       [ControllerName(LINUXCNC, "[TRAJ] MAX_LINEAR_VELOCITY", "units/s")]),
    "interpolator.path_acc_max_mm_s2": ("path acceleration limit",
                                        [ControllerName(LINUXCNC, "[TRAJ] MAX_LINEAR_ACCELERATION", "units/s^2")]),
    "sim.feed_override.override": ("feed override", [ControllerName(LINUXCNC, "[DISPLAY] MAX_FEED_OVERRIDE",
                                                                    "its upper bound; the dial is the operator's")]),
}
_AXIS_KEY = re.compile(r"^axes\.([a-z])\.([a-z_]+)$")


def controllers_of(controller: str) -> tuple[str, ...]:
    """The controllers whose names a profile with this `controller` text gets."""
    text = controller.lower()
    named = tuple(c for c in CONTROLLERS if c.lower() in text or (c == SINUMERIK and "siemens" in text))
    return named or CONTROLLERS


def names_for(key: str, controller: str = "") -> list[ControllerName]:
    """The controller's names for a profile key (empty when none is known)."""
    wanted = controllers_of(controller)
    m = _AXIS_KEY.match(key)
    if m:
        entry = _AXIS.get(m.group(2))
        if entry is None:
            return []
        letter = m.group(1).upper()
        return [ControllerName(n.controller, n.name.format(A=letter), n.note) for n in entry[1]
                if n.controller in wanted]
    entry = _OTHER.get(key)
    return [n for n in entry[1] if n.controller in wanted] if entry else []


def label(key: str) -> str:
    """The key in plain words: `axes.y.acc_max` -> "Y-axis maximum acceleration"."""
    m = _AXIS_KEY.match(key)
    if m and m.group(2) in _AXIS:
        return f"{m.group(1).upper()}-axis {_AXIS[m.group(2)][0]}"
    if key in _OTHER:
        return _OTHER[key][0]
    return key.rsplit(".", 1)[-1].replace("_", " ")


def with_names(key: str, controller: str = "") -> str:
    """`axes.y.acc_max` (LinuxCNC INI `[AXIS_Y] MAX_ACCELERATION` (units/s^2)): the key for reports."""
    names = names_for(key, controller)
    return f"`{key}`" + (f" ({'; '.join(n.text() for n in names)})" if names else "")
