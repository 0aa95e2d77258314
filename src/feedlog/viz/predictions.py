"""A trained model's prediction for a part program, as the tables viz overlays (`ModelPrediction`).

train's `predict_program` does the work; this module only turns its answer into per-block times
(`block`, `duration_s`) and, when the model predicts a feed along the path, a feed series.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.errors import ModelError
from feedlog.profile import MachineProfile
from feedlog.viz.prepare import ModelPrediction
from feedlog.viz.stages import stage_function


def _block_table(result: Any) -> pd.DataFrame | None:
    table = result if isinstance(result, pd.DataFrame) else getattr(result, "blocks", None)
    if table is None:
        return None
    for col in ("duration_s", "predicted_duration_s", "pred_duration_s"):
        if col in table.columns and "block" in table.columns:
            return pd.DataFrame({"block": table["block"].to_numpy(dtype=np.int64),
                                 "duration_s": table[col].to_numpy(dtype=np.float64)})
    raise ModelError(f"prediction has no per-block duration column; it has {list(table.columns)}")


def from_result(name: str, result: Any) -> ModelPrediction:
    """Wrap what `predict_program` returned (a block table or an object with `.blocks`)."""
    blocks = _block_table(result)
    cycle = getattr(result, "cycle_time_s", None)
    if cycle is None and blocks is not None:
        cycle = float(np.nansum(blocks["duration_s"].to_numpy()))
    series = getattr(result, "series", None)
    if series is not None and not {"t_ns", "feed_mm_min"} <= set(series.columns):
        series = None
    return ModelPrediction(name=name, blocks=blocks, series=series,
                           cycle_time_s=None if cycle is None else float(cycle))


def model_prediction(checkpoint: str | Path | Any, program: Any, *, profile: MachineProfile | None = None,
                     name: str | None = None) -> ModelPrediction:
    """Predict `program` with the model saved at `checkpoint` (a path, or a model train/ already loaded),
    named after the file unless `name` is given."""
    predict_program = stage_function("predict_program")
    if isinstance(checkpoint, (str, Path)):
        path = Path(checkpoint)
        if not path.is_file():
            raise ModelError(f"{path}: model checkpoint not found")
        name = name or path.stem
    result = predict_program(program, checkpoint, profile)
    return from_result(name or getattr(checkpoint, "name", "model"), result)
