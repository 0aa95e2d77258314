"""Predicting a part program's block times and cycle time with a trained checkpoint."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.errors import ModelError, ProgramError
from feedlog.profile import MachineProfile, load_profile
from feedlog.train.checkpoint import SUFFIX, load_checkpoint
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import with_program_columns
from feedlog.train.model_hybrid import HybridModel, attach_sim
from feedlog.train.registry import Model
from feedlog.toolpath.limits import check_axes


@dataclass
class Prediction:
    """`blocks`: block, line, kind, nominal_time_s (CAM) and duration_s (predicted; NaN for models that
    only predict the whole program); `cycle_time_s` includes the program's dwells."""

    model: str
    cycle_time_s: float
    cam_time_s: float
    blocks: pd.DataFrame
    fingerprint: str = ""
    profile: str = ""
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "cycle_time_s": self.cycle_time_s, "cam_time_s": self.cam_time_s,
                "blocks": int(len(self.blocks)), "profile": self.profile, "fingerprint": self.fingerprint,
                "notes": list(self.notes)}


def _looks_like_checkpoint(value: Any) -> bool:
    return isinstance(value, Model) or (isinstance(value, (str, Path)) and str(value).endswith(SUFFIX)
                                        and Path(value).is_file())


def model_profile_for(model: Model, program: Any) -> tuple[MachineProfile | None, str]:
    """The machine profile to predict `program` with when none is given: among the profiles the model
    was trained on (`params["profiles"]`, or the one `params["profile"]`), the one with the fewest axes
    that has every axis the program moves; ProgramError (via `check_axes`) when none has them all.
    Returns (profile, a note saying which was chosen, or "")."""
    names = list(model.params.get("profiles") or ([model.params["profile"]] if model.params.get("profile") else []))
    if not names:
        return None, ""
    profiles = [load_profile(str(n)) for n in names]
    fitting = []
    for prof in profiles:
        try:
            check_axes(program.blocks, tuple(prof.axes), prof.name)
            fitting.append(prof)
        except ProgramError:
            continue
    if not fitting:
        moved = [a for a in "abc" if f"{a}_deg" in program.blocks.columns]
        check_axes(program.blocks, tuple(profiles[0].axes), profiles[0].name)  # raises, naming the axis
        raise ModelError(f"no profile the model was trained on ({', '.join(names)}) has the program's axes {moved}; "
                         "give --profile")
    chosen = min(fitting, key=lambda p: len(p.axes))
    note = (f"profile {chosen.name}: the one of the model's training machines ({', '.join(names)}) with the "
            "program's axes (--profile to choose another)") if len(names) > 1 else ""
    return chosen, note


def predict_program(program: Any, checkpoint: str | Path | Model, profile: MachineProfile | str | None = None,
                    *, name: str | None = None, lenient: bool = False, dialect: str = "auto") -> Prediction:
    """Predict `program` (path, G-code text or parsed Program) with a checkpoint (path or loaded Model).

    `profile` defaults to the profile the model was trained with. For convenience the first two
    arguments may also come in the order (checkpoint, program).
    """
    if _looks_like_checkpoint(program) and not _looks_like_checkpoint(checkpoint):
        program, checkpoint = checkpoint, program
    from feedlog.toolpath import block_features, load_program

    model = checkpoint if isinstance(checkpoint, Model) else load_checkpoint(checkpoint)
    model.check_trained()
    parsed = program if hasattr(program, "blocks") else load_program(program, lenient=lenient, dialect=dialect)
    notes: list[str] = []
    if profile is None:
        prof, why = model_profile_for(model, parsed)
        if why:
            notes.append(why)
    else:
        prof = load_profile(profile) if isinstance(profile, (str, Path)) else profile
    if prof is not None:
        check_axes(parsed.blocks, tuple(prof.axes), prof.name)
    features = with_program_columns(block_features(parsed, prof), parsed, prof)
    label = name or str(getattr(parsed, "name", "") or (Path(program).stem if isinstance(program, Path) else "program"))
    table = ProgramTable(label, features, profile=prof, split="test")
    if isinstance(model, HybridModel):
        if prof is None:
            raise ModelError("the hybrid model needs a machine profile to simulate (--profile)")
        table = attach_sim(table, program=parsed)
    result = model.predict(table)
    dwell = float(np.nansum(parsed.blocks["dwell_s"].to_numpy(np.float64))) if "dwell_s" in parsed.blocks else 0.0
    blocks = features[["block", "line", "kind", "nominal_time_s"]].copy()
    blocks["duration_s"] = result.durations_s if result.durations_s is not None else np.nan
    notes += list(result.notes) + list(getattr(parsed, "warnings", []))
    if result.durations_s is None:
        notes.append(f"{model.name} predicts the whole program only; per-block durations are NaN")
    if dwell:
        notes.append(f"includes {dwell:.3f} s of programmed dwell")
    return Prediction(model=model.name, cycle_time_s=result.cycle_time_s + dwell,
                      cam_time_s=float(np.nansum(features["nominal_time_s"].to_numpy())) + dwell,
                      blocks=blocks, fingerprint=model.fingerprint, profile=getattr(prof, "name", ""),
                      notes=notes)
