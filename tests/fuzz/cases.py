"""What a fuzz case is: input files, the commands run on them, and what each run must end in."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures" / "ingest"
PROGRAMS = ROOT / "recordings" / "programs"
EXAMPLES = ROOT / "examples"

# what a run may end in: "ok" (exit 0, sane output), "error" (a clear error line), "any" (either)
EXPECTATIONS = ("ok", "error", "any")


@dataclass
class Run:
    """One command on the case's files. `argv` names files relative to the case folder.

    `same_as_seed`: the run must succeed and report what the unmutated seed reports (for mistakes
    that do not change the content: line endings, a BOM, padded cells); `max_dropped_ratio` bounds
    `dropped_frames / frames` of an imported CAN log."""

    argv: list[str]
    expect: str = "any"
    same_as_seed: bool = False
    max_dropped_ratio: float | None = None

    def __post_init__(self) -> None:
        if self.expect not in EXPECTATIONS:
            raise ValueError(f"expect={self.expect!r}")
        if self.same_as_seed:
            self.expect = "ok"


@dataclass
class Case:
    """`files` are written into an empty folder. An error must name `input` (the bad file, or the bad
    argument) and, when `located`, where in it (line, byte, record, frame, ...)."""

    kind: str
    name: str
    files: dict[str, bytes]
    runs: list[Run]
    input: str
    seed: dict[str, bytes] = field(default_factory=dict)  # the unmutated files, for same_as_seed runs
    located: bool = True
