"""LinuxCNC machines that differ from the shipped reference machines in known ways.

`derive_machine(base, folder, changes=..., feedback_lag=...)` writes a copy of recordings/configs/<base>.ini
into `folder` with INI keys changed (`("AXIS_X", "MAX_ACCELERATION", 300)`; a joint's limits should
change with its axis) and, optionally, a HAL file that puts a first-order lag (LinuxCNC's `lowpass`
component, gain 1 - exp(-T / tau)) between a joint's simulated drive and its position feedback, and with
HAL parameters of the copied HAL files changed (`hal_params={"xyzac-trt-kins.y-offset": 22.5}`: the
trunnion's geometry).
`feedlog diagnose`'s integration tests and the bundled mystery machine (scripts/make_recordings.py)
are made this way: record on the variant, diagnose with the shipped profile, expect the change back.
A `backlash={joint: width_mm}` puts mechanical play between a joint's simulated drive and its position
feedback, as a table with lost motion in its screw measured by a linear scale would show it (LinuxCNC
ships no play component, so it is made of three standard ones, PLAY_HAL).
"""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Iterable, Mapping
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "recordings" / "configs"
RECORDER_HALFILE = "HALFILE = /tmp/lcnc/record.tcl"

LAG_HAL = """# first-order lag on joint {joint}'s position feedback: lowpass between basic_sim's pid pass-through and its mux
loadrt lowpass names={name}
addf {name} servo-thread
unlinkp J{joint}_mux.in1
net J{joint}:lagged-pos {name}.out => J{joint}_mux.in1
net J{joint}:on-pos => {name}.in
setp {name}.gain {gain:.9f}
"""


# play (backlash) of `width` between joint {joint}'s drive and its feedback: the measured table position p
# follows the drive's d only where d has crossed the play, p += deadzone(d - p, width), every servo cycle.
# Added after basic_sim's mux (the drive as the motion controller commanded it this cycle), it feeds
# motor-pos-fb, which the motion controller reads next cycle: the same one-cycle delay as without it.
PLAY_HAL = """# mechanical play of {width} mm on joint {joint}: the feedback is a play operator of the drive position
loadrt sum2 names={name}_diff,{name}_pos
loadrt deadzone names={name}_dz
addf {name}_diff servo-thread
addf {name}_dz servo-thread
addf {name}_pos servo-thread
setp {name}_diff.gain1 -1
setp {name}_dz.threshold {width:.9f}
unlinkp joint.{joint}.motor-pos-fb
net J{joint}:pos-fb => {name}_diff.in0
net J{joint}:play-gap {name}_diff.out => {name}_dz.in
net J{joint}:play-take {name}_dz.out => {name}_pos.in1
net J{joint}:table-pos {name}_pos.out => {name}_pos.in0 {name}_diff.in1 joint.{joint}.motor-pos-fb
"""


def set_ini_key(text: str, section: str, key: str, value: object) -> str:
    """`text` with `key = value` in `[section]` (replaced where it is, else added at the section's top)."""
    pattern = re.compile(rf"(^\[{re.escape(section)}\]\n(?:(?!^\[).*\n)*?)^{re.escape(key)}\s*=.*$", re.M)
    if pattern.search(text):
        return pattern.sub(lambda m: f"{m.group(1)}{key} = {value}", text, count=1)
    head = re.compile(rf"^\[{re.escape(section)}\]\n", re.M)
    if not head.search(text):
        raise ValueError(f"the INI has no [{section}] section")
    return head.sub(f"[{section}]\n{key} = {value}\n", text, count=1)


def set_hal_param(text: str, param: str, value: object) -> str:
    """`text` (a HAL file) with `setp param value` replacing the file's own setp of `param`."""
    pattern = re.compile(rf"^setp\s+{re.escape(param)}\s+\S+\s*$", re.M)
    if not pattern.search(text):
        raise ValueError(f"the HAL file sets no {param}")
    return pattern.sub(f"setp {param} {value}", text, count=1)


def derive_machine(base: str, folder: str | Path, *, changes: Iterable[tuple[str, str, object]] = (),
                   feedback_lag: Mapping[int, float] | None = None, name: str | None = None,
                   hal_params: Mapping[str, object] | None = None,
                   backlash: Mapping[int, float] | None = None) -> Path:
    """Write the variant's INI (and its HAL files) into `folder`; return the INI's path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    text = (CONFIGS / f"{base}.ini").read_text()
    for section, key, value in changes:
        text = set_ini_key(text, section, key, value)
    for hal in CONFIGS.glob("*.hal"):  # relative HALFILEs (trt.hal) stay next to the INI
        if f"HALFILE = {hal.name}" in text:
            shutil.copyfile(hal, folder / hal.name)
    left = dict(hal_params or {})
    for hal in sorted(folder.glob("*.hal")):
        hal_text = hal.read_text()
        for param in [p for p in left if re.search(rf"^setp\s+{re.escape(p)}\s", hal_text, re.M)]:
            hal_text = set_hal_param(hal_text, param, left.pop(param))
        hal.write_text(hal_text)
    if left:
        raise ValueError(f"no HAL file of {base} sets {', '.join(left)}")
    period_s = float(re.search(r"^SERVO_PERIOD\s*=\s*(\d+)", text, re.M).group(1)) / 1e9
    extra = []
    for joint, tau in sorted((feedback_lag or {}).items()):
        hal_name = f"lag_j{joint}.hal"
        gain = 1.0 - math.exp(-period_s / tau)
        (folder / hal_name).write_text(LAG_HAL.format(joint=joint, name=f"feedlog_lag_j{joint}", gain=gain))
        extra.append(f"HALFILE = {hal_name}")
    for joint, width in sorted((backlash or {}).items()):
        hal_name = f"play_j{joint}.hal"
        (folder / hal_name).write_text(PLAY_HAL.format(joint=joint, name=f"feedlog_play_j{joint}", width=width))
        extra.append(f"HALFILE = {hal_name}")
    if extra:
        if RECORDER_HALFILE not in text:
            raise ValueError("the base INI has no recorder HALFILE line to put the lag or play before")
        text = text.replace(RECORDER_HALFILE, "\n".join([*extra, RECORDER_HALFILE]))
    ini = folder / f"{name or folder.name}.ini"
    ini.write_text(text)
    return ini
