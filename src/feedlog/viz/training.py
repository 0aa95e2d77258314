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
    loaded: dict[str, Any] = field(default_factory=dict)         # model name -> model loaded for prediction


DEMO_MODELS = ("mlp", "bilstm-block", "bilstm-final", "hybrid")  # bilstm-r is a per-sample model: not a cycle-time one


def program_table(run: RecordingRun):
    """train's ProgramTable for an aligned run (block features and measured block times from align), with
    the program columns `feedlog train` attaches when it reads align's output (`with_program_columns`:
    axis times, path limits, G64 Q), so the demo trains on what `feedlog predict` later computes from the
    program alone: the model columns of report.md and models/results.md are then the same numbers."""
    from feedlog.train import ProgramTable  # train is optional: imported only when it exists
    from feedlog.train.features import with_program_columns

    g = run.gathered
    blocks = with_program_columns(g.aligned.blocks, g.program, g.profile) if g.program is not None else g.aligned.blocks
    return ProgramTable(run.entry.name, blocks, program=run.entry.family or run.entry.program,
                        split=run.entry.split, points=g.aligned.points, profile=g.profile,
                        program_text=run.recording.program_text if run.recording is not None else None)


def train_models(runs: Sequence[RecordingRun], *, out_dir: Path, models: Sequence[str] | None = None,
                 preset: str = "quick", log: Callable[[str], None] = print, runner: Any = None,
                 progress: bool = False) -> TrainOutcome:
    """Train on the runs that were aligned; a missing train/ or align/ stage is reported, not faked.

    `runner` (feedlog.execution.TaskRunner) runs the hybrid's simulations; training runs here. `progress`:
    per-epoch bars on a terminal."""
    try:
        train_and_evaluate = stage_function("train_and_evaluate")
        stage_function("predict_program")
    except StageMissing as exc:
        return TrainOutcome(available=False, reason=str(exc))
    aligned = [r for r in runs if r.gathered is not None and r.gathered.aligned is not None]
    if not aligned:
        return TrainOutcome(available=False, reason="no recording could be aligned, so there is nothing to train on")
    names = tuple(models) if models else DEMO_MODELS
    log(f"training {', '.join(names)} ({preset} preset) on {sum(r.entry.split == 'train' for r in aligned)} "
        f"recordings, testing on {sum(r.entry.split == 'test' for r in aligned)}")
    try:
        tables = [program_table(r) for r in aligned]
        results = train_and_evaluate(tables, out_dir=out_dir, models=names, preset=preset, overwrite=True,
                                     progress=progress, log=log, runner=runner)
    except FeedlogError as exc:
        return TrainOutcome(available=False, reason=f"training failed: {exc}")
    except Exception as exc:  # noqa: BLE001 - a bug in train/ must not stop the main job
        return TrainOutcome(available=False, reason=f"training failed with an internal error "
                                                    f"({type(exc).__name__}: {exc})")
    summary = results.attrs.get("summary", {})
    checkpoints = {name: Path(info["checkpoint"]) for name, info in summary.items() if "checkpoint" in info}
    notes = [f"trained with the {preset} preset"
             + (" (few epochs, so that the demo stays short); the README and docs/train.md quote the full preset "
                "(`feedlog train --preset full`), so their figures differ" if preset != "full" else "")]
    notes += [f"{name}: skipped ({info['skipped']})" for name, info in summary.items() if "skipped" in info]
    notes += [f"{name}: trained in {info['train_s']} s" for name, info in summary.items() if "train_s" in info]
    notes += [f"{rec}: not evaluated ({why})" for rec, why in results.attrs.get("not_evaluated", {}).items()]
    not_aligned = [r.entry.name for r in runs if r not in aligned]
    if not_aligned:
        notes.append(f"not used for training (not aligned): {', '.join(not_aligned)}")
    return TrainOutcome(available=True, checkpoints=checkpoints, evaluation=results, notes=notes)


def predict_for(outcome: TrainOutcome | None, run: RecordingRun) -> dict[str, ModelPrediction]:
    """Every trained model's prediction for the run's program (failures noted on the run)."""
    if outcome is None or not outcome.available:
        return {}
    out: dict[str, ModelPrediction] = {}
    from feedlog.train import load_checkpoint

    from feedlog.viz.predictions import model_prediction
    for name, checkpoint in outcome.checkpoints.items():
        try:
            if name not in outcome.loaded:  # load each checkpoint once for all recordings
                outcome.loaded[name] = load_checkpoint(checkpoint)
            out[name] = model_prediction(outcome.loaded[name], run.gathered.program, profile=run.gathered.profile,
                                         name=name)
        except FeedlogError as exc:
            run.errors.append(f"prediction with {name} failed: {exc}")
        except Exception as exc:  # noqa: BLE001 - a bug in train/ must not stop the main job
            run.errors.append(f"prediction with {name} failed with an internal error ({type(exc).__name__}: {exc})")
    return out
