"""The demo's learning step: train models on the aligned recordings, predict every recording's program.

Thin glue over train/ (`train_and_evaluate`, `predict_program`): trained checkpoints go to
`<out>/models/<name>.pt` so that `feedlog predict --model` can use them later.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from feedlog.errors import FeedlogError
from feedlog.viz.prepare import ModelPrediction
from feedlog.viz.stages import StageMissing, stage_function

if TYPE_CHECKING:
    from feedlog.viz.pipeline import RecordingRun


@dataclass
class TrainOutcome:
    available: bool
    reason: str = ""
    checkpoints: dict[str, Path] = field(default_factory=dict)   # model name -> .pt
    evaluation: Any = None                                       # train's own evaluation table, when given
    notes: list[str] = field(default_factory=list)


def train_models(runs: Sequence[RecordingRun], *, out_dir: Path, models: Sequence[str] | None = None,
                 preset: str = "quick", log: Callable[[str], None] = print) -> TrainOutcome:
    """Train on the runs that were aligned; a missing train/ or align/ stage is reported, not faked."""
    try:
        stage_function("train_and_evaluate")
        stage_function("predict_program")
    except StageMissing as exc:
        return TrainOutcome(available=False, reason=str(exc))
    aligned = [r for r in runs if r.gathered is not None and r.gathered.aligned is not None]
    if not aligned:
        return TrainOutcome(available=False, reason="no recording could be aligned, so there is nothing to train on")
    raise StageMissing("training is not wired into the demo yet")


def predict_for(outcome: TrainOutcome | None, run: RecordingRun) -> dict[str, ModelPrediction]:
    """Every trained model's prediction for the run's program (failures noted on the run)."""
    if outcome is None or not outcome.available:
        return {}
    out: dict[str, ModelPrediction] = {}
    from feedlog.viz.predictions import model_prediction
    for name, checkpoint in outcome.checkpoints.items():
        try:
            out[name] = model_prediction(checkpoint, run.gathered.program, profile=run.gathered.profile, name=name)
        except FeedlogError as exc:
            run.errors.append(f"prediction with {name} failed: {exc}")
    return out
