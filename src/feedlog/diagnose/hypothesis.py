"""Candidate causes: one profile parameter each, with bounds, how to search it and what it predicts.

A `Hypothesis` names a parameter by its dotted profile key (`feedlog.diagnose.keys`), the value the
profile has in force (`baseline`; `switches_on` when the parameter belongs to a mechanism the profile
has switched off, which the hypothesis switches on), its bounds and search scale, the residual level it
is judged on (`timing`: segment times from re-simulation; `feedback`: feedback positions from the
recording's own command; `line`: the line stream against the positions; `geometry`: the commanded joints
from the recording's own axis positions through the kinematics) and the residual pattern
it predicts (shown with a finding).

Hypotheses come from *families*, one module each, registered in `FAMILIES` (name -> "module:FAMILY").
A family is a `Family`: its `candidates(profile, cases)` are the hypotheses the data can speak to (an
axis that never moves offers no hypothesis about it); its `rank` breaks ties between equally good
explanations (lower first: the operator's dials before the machine's limits before planner settings);
and it reads the evidence the data gives without any simulation for its own keys (`describe`,
`suggest`, `contradicts`). A family that declares no rank, or leaves out one of the three evidence
methods, cannot be made (an error at import, caught by tests/diagnose/test_families.py), so it is
never silently ranked last or left without evidence. Adding a family is one module and one line here;
docs/diagnose.md shows one.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

from feedlog.diagnose import keys
from feedlog.errors import FeedlogError
from feedlog.profile import MachineProfile
from feedlog.registry import Registry

if TYPE_CHECKING:
    from feedlog.diagnose.evidence import Evidence

SCALES = ("log", "linear", "int", "choice")
LEVELS = ("timing", "feedback", "line", "geometry")
# The least data a cause is judged on: so many of the level's units (timing: segments, line: blocks,
# feedback: samples) and MIN_SECONDS of motion. Below that a parameter fits the noise of a handful of
# blocks (a 0.5 s cut once "found" a feed override of 2, a 1 s cut of 15 segments a blend tolerance);
# two programs at 5 Hz (11 long segments over 20 s) still carry an axis limit.
MIN_DATA = {"timing": 8, "line": 8, "feedback": 1000, "geometry": 1000}
MIN_SECONDS = 5.0

# family name -> "module:FAMILY" (a `Family`). One line per family.
FAMILIES: Registry[Family] = Registry.lazy("hypothesis family", {
    "axis_limits": "feedlog.diagnose.hyp_axes:FAMILY",
    "path_limits": "feedlog.diagnose.hyp_path:FAMILY",
    "overrides": "feedlog.diagnose.hyp_override:FAMILY",
    "planner": "feedlog.diagnose.hyp_planner:FAMILY",
    "dwell": "feedlog.diagnose.hyp_dwell:FAMILY",
    "tool_change": "feedlog.diagnose.hyp_tool_change:FAMILY",
    "feedback": "feedlog.diagnose.hyp_feedback:FAMILY",
    "logger": "feedlog.diagnose.hyp_logger:FAMILY",
    "geometry": "feedlog.diagnose.hyp_geometry:FAMILY",
}, sort_known=True)


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


class Family(ABC):
    """One family of candidate causes: what it offers, how it ranks, what the data alone says about it.

    A subclass sets `name` (its key in `FAMILIES`) and `rank` (an integer; among equally good
    explanations the family of the lowest rank is named first) and implements all four methods; a
    family whose keys the evidence says nothing about says so in its methods ('' / () / None)."""

    name: ClassVar[str]
    rank: ClassVar[int]

    def __init__(self) -> None:
        cls = type(self)
        if not isinstance(getattr(cls, "name", None), str) or not cls.name:
            raise FeedlogError(f"hypothesis family {cls.__name__}: declares no name")
        rank = getattr(cls, "rank", None)
        if not isinstance(rank, int) or isinstance(rank, bool):
            raise FeedlogError(f"hypothesis family {cls.name}: declares no integer rank (got {rank!r})")

    @abstractmethod
    def candidates(self, profile: MachineProfile, cases: Sequence[Any]) -> list[Hypothesis]:
        """The hypotheses of this family the recordings can speak to."""

    @abstractmethod
    def describe(self, ev: Evidence, key: str, fitted: Any = None) -> str:
        """What the data itself says about `key`, in a sentence ('' when it says nothing)."""

    @abstractmethod
    def suggest(self, ev: Evidence, key: str, baseline: Any) -> tuple[float, ...]:
        """Values of `key` the data points at (they join the search grid; the loss alone decides)."""

    @abstractmethod
    def contradicts(self, ev: Evidence, key: str, profile_value: Any, fitted: Any) -> str | None:
        """Why the data itself rules out `key` = `fitted` (None when it does not)."""


def family(name: str) -> Family:
    """The registered family `name`; an unknown name is an error listing the known ones."""
    fam = FAMILIES.get(name)
    if not isinstance(fam, Family) or fam.name != name:
        raise FeedlogError(f"hypothesis family {name!r}: {FAMILIES.target(name)} is not a Family named {name!r}")
    return fam


def rank(name: str) -> int:
    """The tie-break rank of family `name` (lower first)."""
    return family(name).rank


def candidates(profile: MachineProfile, cases: Sequence[Any], *, families: Sequence[str] | None = None,
               exclude: Sequence[str] = ()) -> list[Hypothesis]:
    """Every candidate of the named families (default: all) that the data can speak to."""
    out: list[Hypothesis] = []
    seen: set[str] = set()
    for name in families or FAMILIES:
        for hyp in family(name).candidates(profile, cases):
            if hyp.key in seen or hyp.key in exclude:
                continue
            seen.add(hyp.key)
            out.append(hyp)
    return out
