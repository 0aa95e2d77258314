"""Late-bound access to the other pipeline stages, so viz and the demo run with whichever exist.

Every stage function viz calls is named here once (`STAGE_FUNCTIONS`: name -> module, attribute) and
imported on first use. A stage that is not importable in this checkout raises `StageMissing`
(a FeedlogError) saying which function is missing and why; `availability()` lists them all for a
report. Nothing is faked: a missing stage yields no numbers, only the reason.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from feedlog.errors import FeedlogError

# name -> (module, attribute). One line per function viz calls in another stage.
STAGE_FUNCTIONS: dict[str, tuple[str, str]] = {
    "read_recording": ("feedlog.ingest", "read_recording"),
    "parse_program": ("feedlog.toolpath", "load_program"),
    "cl_points": ("feedlog.toolpath", "cl_points"),
    "block_features": ("feedlog.toolpath", "block_features"),
    "simulate": ("feedlog.sim", "simulate"),
    "align_recording": ("feedlog.align", "align_recording"),
    "train_and_evaluate": ("feedlog.train", "train_and_evaluate"),
    "predict_program": ("feedlog.train", "predict_program"),
}

# pipeline stage -> the functions it needs
STAGES: dict[str, tuple[str, ...]] = {
    "ingest": ("read_recording",),
    "toolpath": ("parse_program", "cl_points"),
    "sim": ("simulate",),
    "align": ("align_recording",),
    "train": ("train_and_evaluate", "predict_program"),
}


class StageMissing(FeedlogError):
    """A pipeline stage this command needs is not available in this installation."""


def stage_function(name: str) -> Callable[..., Any]:
    """The stage function `name` (see STAGE_FUNCTIONS), or StageMissing naming what is absent."""
    try:
        module_name, attr = STAGE_FUNCTIONS[name]
    except KeyError:
        raise FeedlogError(f"unknown stage function {name!r}; known: {', '.join(STAGE_FUNCTIONS)}") from None
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise StageMissing(f"{module_name}.{attr} is not available ({module_name} cannot be imported: {exc})") \
            from None
    fn = getattr(module, attr, None)
    if fn is None:
        raise StageMissing(f"{module_name}.{attr} is not available ({module_name} has no {attr} yet)")
    return fn


def missing_reason(stage: str) -> str | None:
    """Why a pipeline stage cannot run here, or None when all its functions are importable."""
    for name in STAGES[stage]:
        try:
            stage_function(name)
        except StageMissing as exc:
            return str(exc)
    return None


def availability() -> dict[str, str | None]:
    """Pipeline stage -> None when available, else the reason it is not."""
    return {stage: missing_reason(stage) for stage in STAGES}
