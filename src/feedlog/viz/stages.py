"""Late-bound access to the other pipeline stages, so viz and the demo run with whichever exist.

Every stage function viz calls is named here once (`STAGE_FUNCTIONS`: name -> "module:attribute") and
imported on first use. A stage that is not importable in this checkout raises `StageMissing`
(a FeedlogError) saying which function is missing and why; `availability()` lists them all for a
report. Nothing is faked: a missing stage yields no numbers, only the reason.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from feedlog.errors import FeedlogError
from feedlog.registry import Registry, TargetMissing


class StageMissing(FeedlogError):
    """A pipeline stage this command needs is not available in this installation."""


def _missing(module: str, attribute: str, cause: ImportError | None) -> StageMissing:
    why = f"{module} cannot be imported: {cause}" if cause is not None else f"{module} has no {attribute} yet"
    return StageMissing(f"{module}.{attribute} is not available ({why})")


def _unavailable(name: str, missing: TargetMissing) -> StageMissing:
    return _missing(missing.module, missing.attribute, missing.cause)


# name -> "module:attribute". One line per function viz calls in another stage.
STAGE_FUNCTIONS: Registry[Callable[..., Any]] = Registry.lazy("stage function", {
    "read_recording": "feedlog.ingest:read_recording",
    "parse_program": "feedlog.toolpath:load_program",
    "cl_points": "feedlog.toolpath:cl_points",
    "block_features": "feedlog.toolpath:block_features",
    "simulate": "feedlog.sim:simulate",
    "align_recording": "feedlog.align:align_recording",
    "train_and_evaluate": "feedlog.train:train_and_evaluate",
    "predict_program": "feedlog.train:predict_program",
}, unavailable=_unavailable)

# pipeline stage -> the functions it needs
STAGES: dict[str, tuple[str, ...]] = {
    "ingest": ("read_recording",),
    "toolpath": ("parse_program", "cl_points"),
    "sim": ("simulate",),
    "align": ("align_recording",),
    "train": ("train_and_evaluate", "predict_program"),
}


def stage_function(name: str) -> Callable[..., Any]:
    """The stage function `name` (see STAGE_FUNCTIONS), or StageMissing naming what is absent."""
    try:
        return STAGE_FUNCTIONS.get(name)
    except ImportError as exc:   # the stage's module exists but something it imports does not
        module, _, attribute = (STAGE_FUNCTIONS.target(name) or "").partition(":")
        raise _missing(module, attribute, exc) from None


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
