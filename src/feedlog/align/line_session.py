"""A line stream read as a session: numbering, the program that ran, and the events in between.

`session_lines` is what align (and diagnose's block level) does with a recording that has a line
stream but no positions, before any block is timed:
1. the time the program expects per line: the simulation under the given profile (else the generic
   one: only the relative times matter here);
2. what the recorded values count (`line_numbering.detect`, or the stated `numbering`);
3. where the data ties recorded lines to program lines (`session_events.anchors`) and where the
   recorded lines stop being the program's (`line_map.map_lines`);
4. the events (tool changes, stops, waits, standstills: `session_events.find_events`).
It returns the line samples in program lines (runs the data cannot place dropped) and a `Session`
whose `report` goes into align's report.json under `numbering`, `line_map` and `events`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.align.blocks import line_runs
from feedlog.align.line_map import LineMap, map_lines
from feedlog.align.line_numbering import Numbering, detect, program_line
from feedlog.align.session_events import MIN_STILL_S, anchors, find_events, line_codes, motion_feed, still_ns
from feedlog.profile import MachineProfile, load_profile
from feedlog.recording import Recording
from feedlog.toolpath import Program
from feedlog.toolpath.schema import RAPID


@dataclass
class Session:
    numbering: Numbering
    line_map: LineMap
    events: pd.DataFrame
    runs: pd.DataFrame                 # recorded runs: line (recorded), program_line, t_start_ns, t_end_ns
    expected: pd.Series                # seconds the simulation expects per program line
    warnings: list[str] = field(default_factory=list)

    @property
    def report(self) -> dict:
        t0 = int(self.runs["t_start_ns"].iloc[0]) if len(self.runs) else 0
        events = [{**{k: v for k, v in e.items() if k not in ("t_start_ns", "t_end_ns")},
                   "t_s": (e["t_start_ns"] - t0) / 1e9} for e in self.events.to_dict("records")]
        by_kind = self.events.groupby("kind")["duration_s"].agg(["count", "sum"]) if len(self.events) else None
        return {"numbering": self.numbering.as_dict(), "line_map": self.line_map.as_dict(),
                "events": events,
                "events_total_s": {k: {"count": int(r["count"]), "duration_s": float(r["sum"])}
                                   for k, r in by_kind.iterrows()} if by_kind is not None else {}}


def expected_times(program: Program, profile: MachineProfile | None) -> pd.Series:
    """Seconds per program line holding a block: simulated motion time (0 without motion)."""
    from feedlog.sim import simulate

    sim = simulate(program, profile if profile is not None else load_profile("generic-xyz"))
    per_line = sim.blocks.groupby("line")["duration_s"].sum()
    out = pd.Series(0.0, index=pd.Index(np.unique(program.blocks["line"].to_numpy(np.int64)), name="line"))
    out.loc[per_line.index.intersection(out.index)] = per_line.reindex(per_line.index.intersection(out.index))
    return out


def session_lines(recording: Recording, program: Program, profile: MachineProfile | None, t_ns: np.ndarray,
                  values: np.ndarray, numbering: str = "auto") -> tuple[np.ndarray, np.ndarray, Session]:
    """(sample times, program lines, Session): see the module docstring."""
    raw = line_runs(t_ns, values)
    raw["dur_s"] = (raw["t_end_ns"] - raw["t_start_ns"]) / 1e9
    expected = expected_times(program, profile)
    found = detect(raw["line"].to_numpy(), raw["dur_s"].to_numpy(), program, expected, stated=numbering)
    mapped = program_line(raw["line"].to_numpy(), program, found.name)
    runs = raw.assign(line=np.where(np.isfinite(mapped), mapped, -1).astype(np.int64))
    runs = runs[runs["line"] > 0].reset_index(drop=True)
    t0 = int(t_ns[0]) if len(t_ns) else 0
    codes = line_codes(program)
    event_lines = set(codes.index[(codes["codes"].map(len) > 0).to_numpy() | ~codes["moves"].to_numpy()].tolist())
    feed = motion_feed(recording)
    still = np.array([still_ns(feed, int(a), int(b)) / 1e9 if d >= MIN_STILL_S else 0.0
                      for a, b, d in zip(runs["t_start_ns"], runs["t_end_ns"], runs["dur_s"])])
    lmap = map_lines(runs["line"].to_numpy(), runs["dur_s"].to_numpy(), (runs["t_start_ns"].to_numpy() - t0) / 1e9,
                     expected, event_lines, anchors(recording, runs, program, expected), still,
                     rapid_lines=set(program.blocks.loc[program.blocks["kind"].astype(str) == RAPID, "line"].tolist()))
    runs["program_line"] = lmap.program_lines(runs["line"].to_numpy())
    span = (int(runs["t_start_ns"].iloc[0]), int(runs["t_end_ns"].iloc[-1])) if len(runs) else (0, 0)
    events = find_events(recording, runs[["line", "t_start_ns", "t_end_ns"]], runs["program_line"].to_numpy(),
                         program, span_ns=span)
    warnings = []
    if not found.stated:
        warnings.append(f"recorded block values read as {found.name} (detected from the line times against the "
                        f"program; state it with --numbering)")
    mismatch = lmap.warning(program.name)
    if mismatch:
        warnings.append(mismatch)
    # one sample per run start (0 where the data cannot place the run: no block is timed over it) and
    # the last run's end; blocks_from_lines reads the runs back
    placed = runs["program_line"].fillna(0).to_numpy(np.int64)
    t_out = np.r_[runs["t_start_ns"].to_numpy(np.int64), runs["t_end_ns"].to_numpy(np.int64)[-1:]]
    l_out = np.r_[placed, placed[-1:]]
    session = Session(found, lmap, events, runs, expected, warnings)
    return t_out, l_out, session


__all__ = ["Session", "expected_times", "session_lines"]
