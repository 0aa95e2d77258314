"""Candidate causes: one profile parameter each, with bounds, how to search it and what it predicts.

A `Hypothesis` names a parameter by its dotted profile key (`feedlog.diagnose.keys`), the value the
profile has in force (`baseline`; `switches_on` when the parameter belongs to a mechanism the profile
has switched off, which the hypothesis switches on), its bounds and search scale, the residual level it
is judged on (`timing`: segment times from re-simulation; `feedback`: feedback positions from the
recording's own command; `line`: the line stream against the positions; `geometry`: the commanded joints
from the recording's own axis positions through the kinematics) and the residual pattern
it predicts (shown with a finding).

Hypotheses come from *families*, one module each, registered in `FAMILIES` (name -> "module:function");
a family function takes the profile and the prepared cases and returns the candidates the data can
speak to (an axis that never moves offers no hypothesis about it). Adding a family is one module
and one line here; docs/diagnose.md shows one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from feedlog.diagnose import keys
from feedlog.errors import FeedlogError
from feedlog.lazy import load_entry
from feedlog.profile import MachineProfile

SCALES = ("log", "linear", "int", "choice")
LEVELS = ("timing", "feedback", "line", "geometry")
# The least data a cause is judged on: so many of the level's units (timing: segments, line: blocks,
# feedback: samples) and MIN_SECONDS of motion. Below that a parameter fits the noise of a handful of
# blocks (a 0.5 s cut once "found" a feed override of 2, a 1 s cut of 15 segments a blend tolerance);
# two programs at 5 Hz (11 long segments over 20 s) still carry an axis limit.
MIN_DATA = {"timing": 8, "line": 8, "feedback": 1000, "geometry": 1000}
MIN_SECONDS = 5.0

# family name -> "module:function(profile, cases) -> list[Hypothesis]". One line per family.
FAMILIES: dict[str, str] = {
    "axis_limits": "feedlog.diagnose.hyp_axes:candidates",
    "path_limits": "feedlog.diagnose.hyp_path:candidates",
    "overrides": "feedlog.diagnose.hyp_override:candidates",
    "planner": "feedlog.diagnose.hyp_planner:candidates",
    "dwell": "feedlog.diagnose.hyp_dwell:candidates",
    "feedback": "feedlog.diagnose.hyp_feedback:candidates",
    "logger": "feedlog.diagnose.hyp_logger:candidates",
    "geometry": "feedlog.diagnose.hyp_geometry:candidates",
}


@dataclass(frozen=True)
class Hypothesis:
    key: str                        # dotted profile key, as the TOML spells it
    family: str
    lower: float = 0.0
    upper: float = 1.0
    scale: str = "log"              # log / linear (continuous), int (integer search), choice (enumerate)
    choices: tuple[Any, ...] = ()
    baseline: Any = None            # value in force on the profile (None: its mechanism is off)
    switches_on: bool = False       # the parameter's mechanism is off on the profile: fitting it extends the model
    level: str = "timing"
    predicts: str = ""              # the residual pattern this cause produces
    also: dict[str, Any] = field(default_factory=dict)  # keys set together with it (e.g. a switch)
    seeds: tuple[float, ...] = ()   # values the data points at (evidence.suggest): added to the search grid
    min_data: int | None = None     # the least data it is judged on (the level's units); None: MIN_DATA[level]

    def __post_init__(self) -> None:
        keys.split(self.key)
        if self.scale not in SCALES:
            raise FeedlogError(f"hypothesis {self.key}: scale must be one of {', '.join(SCALES)}")
        if self.level not in LEVELS:
            raise FeedlogError(f"hypothesis {self.key}: level must be one of {', '.join(LEVELS)}")
        if self.scale == "choice" and not self.choices:
            raise FeedlogError(f"hypothesis {self.key}: a choice needs choices")
        if self.scale != "choice" and not self.lower < self.upper:
            raise FeedlogError(f"hypothesis {self.key}: need lower < upper, got {self.lower}, {self.upper}")
        if self.scale == "log" and self.lower <= 0:
            raise FeedlogError(f"hypothesis {self.key}: a log scale needs lower > 0, got {self.lower}")

    @property
    def kind(self) -> str:
        """'parameter' (a value of something the model runs) or 'mechanism' (switches one on)."""
        return "mechanism" if self.switches_on else "parameter"

    @property
    def needs(self) -> int:
        """The least data (segments, blocks or samples of its level) this cause is judged on."""
        return MIN_DATA[self.level] if self.min_data is None else self.min_data

    @property
    def unit(self) -> str:
        return keys.unit(self.key)

    @property
    def keys(self) -> set[str]:
        """Every profile key this hypothesis sets."""
        return {self.key, *self.also}

    def values(self, value: Any) -> dict[str, Any]:
        """The profile keys this hypothesis sets for `value`."""
        if self.scale == "int":
            value = int(round(value))
        return {**self.also, self.key: value}


def family_function(name: str):
    return load_entry(FAMILIES, name, what="hypothesis family")


def candidates(profile: MachineProfile, cases: Sequence[Any], *, families: Sequence[str] | None = None,
               exclude: Sequence[str] = ()) -> list[Hypothesis]:
    """Every candidate of the named families (default: all) that the data can speak to."""
    out: list[Hypothesis] = []
    seen: set[str] = set()
    for name in families or FAMILIES:
        for hyp in family_function(name)(profile, cases):
            if hyp.key in seen or hyp.key in exclude:
                continue
            seen.add(hyp.key)
            out.append(hyp)
    return out
