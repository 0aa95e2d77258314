"""The demo's mystery machine: `feedlog diagnose` on recordings/mystery/ (a LinuxCNC machine that is not
quite its shipped profile, scripts/make_mystery.py), written to DEMO-OUT/diagnose/.

`diagnose_mystery(recordings, out)` returns what the report and the console show (the diagnosis'
summary lines and where its report is), or None when there is no mystery folder.
"""

from __future__ import annotations

import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

FOLDER = "mystery"
MANIFEST = "mystery.toml"


@dataclass
class Mystery:
    lines: list[str]
    answer: list[str] = field(default_factory=list)    # the diagnosis in plain sentences (diagnose.plain)
    report: Path | None = None
    images: list[tuple[str, Path]] = field(default_factory=list)
    error: str | None = None
    seconds: float = 0.0


def diagnose_mystery(recordings: Path, out: Path, *, log: Callable[[str], None] = print) -> Mystery | None:
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.diagnose.plain import answer
    from feedlog.diagnose.summary import summary_lines
    from feedlog.diagnose.write import write_outputs
    from feedlog.errors import FeedlogError

    folder = Path(recordings) / FOLDER
    files = sorted(folder.glob("*.mcap"))
    if not files:
        return None
    profile = None
    if (folder / MANIFEST).is_file():
        profile = tomllib.loads((folder / MANIFEST).read_text()).get("profile")
    started = time.perf_counter()
    log(f"diagnose: the mystery machine ({len(files)} recordings)")
    try:
        dx = diagnose(files, profile, config=DiagnoseConfig(learned=False))
        target = out / "diagnose"
        write_outputs(dx, target, overwrite=True)
    except FeedlogError as exc:
        return Mystery(lines=[], error=str(exc), seconds=time.perf_counter() - started)
    images = [(p.stem, p) for p in sorted((target / "plots").glob("*.png"))]
    return Mystery(lines=summary_lines(dx), answer=answer(dx), report=target / "report.md", images=images,
                   seconds=time.perf_counter() - started)
