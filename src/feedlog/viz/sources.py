"""Gather what can be overlaid on one recording by calling the other stages (through viz.stages).

`gather()` parses the recording's program (attached or given), loads its machine profile, aligns,
simulates and predicts with whichever stages are available, and returns `ViewInputs` plus the
stage results (for the demo's table) and notes saying what was left out and why.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.errors import FeedlogError, ProgramError
from feedlog.recording import PROFILE_ATTACHMENT, Recording
from feedlog.profile import MachineProfile, load_profile
from feedlog.viz.prepare import ModelPrediction, ViewInputs
from feedlog.viz.stages import StageMissing, stage_function


@dataclass
class Gathered:
    inputs: ViewInputs
    program: Any = None            # toolpath Program
    profile: MachineProfile | None = None
    aligned: Any = None            # align's result (.points, .blocks, .cycle_time_s)
    sim: Any = None                # SimResult
    notes: list[str] = field(default_factory=list)


def recording_profile(recording: Recording, *, override: str | Path | None = None) -> MachineProfile | None:
    """The profile named on the command line, else the one attached to the recording, else None."""
    if override is not None:
        return load_profile(override)
    data = recording.attachments.get(PROFILE_ATTACHMENT)
    if data is not None:
        return MachineProfile.from_toml(data.decode("utf-8"), source=f"{recording.source}:{PROFILE_ATTACHMENT}")
    machine = recording.metadata.get("machine", "")
    if machine:
        try:
            return load_profile(machine)
        except FeedlogError:
            return None
    return None


def load_program(recording: Recording, *, program: str | Path | None = None, name: str = "program",
                 lenient: bool = False, notes: list[str] | None = None):
    """Parse the given program file, else the program attached to the recording; None when neither.

    Strict first; with `lenient`, a program the strict parser refuses is parsed again leniently and
    every skipped code is named in `notes` (the user sees exactly what was not interpreted).
    """
    parse_program = stage_function("parse_program")
    if program is not None:
        source, label = Path(program), None
    else:
        source, label = recording.program_text, f"{name}.ngc"
        if source is None:
            return None
    try:
        return parse_program(source, name=label)
    except ProgramError as exc:
        if not lenient:
            raise
        parsed = parse_program(source, name=label, lenient=True)
        skipped = ", ".join(f"{u.code} (line {u.line})" for u in parsed.unsupported) or "nothing"
        if notes is not None:
            notes.append(f"program parsed leniently after: {exc}; skipped {skipped}")
        return parsed


def measured_blocks_of(aligned: Any) -> pd.DataFrame | None:
    """align's block table restricted to the columns viz reads."""
    blocks = getattr(aligned, "blocks", None)
    if blocks is None or not len(blocks):
        return None
    return blocks[["block", "t_start_ns", "t_end_ns", "duration_s"]].copy()


def gather(recording: Recording, *, name: str, program: str | Path | None = None,
           profile: str | Path | MachineProfile | None = None, simulate: bool = True, align: bool = True,
           models: list[ModelPrediction] | None = None, arrow_every: int = 50,
           catch_bugs: bool = False, lenient: bool = False) -> Gathered:
    """Everything available to overlay on `recording`; what is not is named in `.notes`.

    With `catch_bugs` an unexpected exception inside align or sim becomes a note too (the demo must
    finish with the stages that work); otherwise it propagates.
    """
    notes: list[str] = []
    caught = Exception if catch_bugs else FeedlogError
    prof = profile if isinstance(profile, MachineProfile) else recording_profile(recording, override=profile)
    if prof is None:
        notes.append("no machine profile (none attached, none given): no simulation, rapids not drawn as commanded")

    prog = path = None
    try:
        prog = load_program(recording, program=program, name=name, lenient=lenient, notes=notes)
        if prog is None:
            notes.append("no part program (none attached, none given): programmed path and blocks not shown")
        else:
            path = stage_function("cl_points")(prog)
    except StageMissing as exc:
        notes.append(f"toolpath: {exc}")
    except Exception as exc:  # noqa: BLE001 - a bad program is the user's error in `view`, a note in the demo
        if not catch_bugs:
            raise
        notes.append(f"toolpath failed: {_describe(exc)}")

    aligned = None
    if align and prog is not None:
        try:
            aligned = stage_function("align_recording")(recording, prog, profile=prof)
        except StageMissing as exc:
            notes.append(f"align: {exc}; block times taken from the recording's line stream")
        except caught as exc:
            notes.append(f"align failed: {_describe(exc)}; block times taken from the recording's line stream")

    sim = None
    if simulate and prog is not None and prof is not None:
        try:
            sim = stage_function("simulate")(prog, prof)
        except StageMissing as exc:
            notes.append(f"sim: {exc}")
        except caught as exc:
            notes.append(f"simulation failed: {_describe(exc)}")

    inputs = ViewInputs(
        recording=recording, name=name,
        program_blocks=None if prog is None else prog.blocks,
        program_path=path,
        sim_series=None if sim is None else sim.series,
        sim_blocks=None if sim is None else sim.blocks,
        measured_blocks=None if aligned is None else measured_blocks_of(aligned),
        models=list(models or []),
        rapid_mm_min=None if prof is None else prof.rapid_mm_min,
        arrow_every=arrow_every,
    )
    return Gathered(inputs=inputs, program=prog, profile=prof, aligned=aligned, sim=sim, notes=notes)


def _describe(exc: Exception) -> str:
    return str(exc) if isinstance(exc, FeedlogError) else f"internal error ({type(exc).__name__}: {exc})"


def finite_or_none(value: Any) -> float | None:
    """A float for tables and JSON, None for missing or non-finite values."""
    if value is None:
        return None
    value = float(value)
    return value if np.isfinite(value) else None
