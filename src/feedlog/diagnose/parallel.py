"""Diagnose's tasks on `feedlog.execution`'s backends: local processes (`-j N`) or a Dask cluster.

Two kinds of task, each a module-level function of one picklable item:
- `prepare_task`: read and align one recording (a path or URL) into a `Case`;
- `held_out_task`: fit one hypothesis without each held-out fold and score the fold (`fit.held_out`);
  on a Dask cluster only (locally, `scorer_pool` shares each re-simulation's recordings out instead).
  The item carries the prepared recordings; a worker builds the level's `Scorer` once per diagnosis
  and keeps it (`_SCORERS`, keyed by the diagnosis' token), so a Dask worker that runs several
  hypotheses, or several steps, re-simulates only what it has not simulated yet.

The results are the ones a serial run computes (the same functions on the same inputs); the stages
never know which backend ran them.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from feedlog.diagnose.cases import Case, prepare_case
from feedlog.diagnose.fit import HeldOut, Scorer, held_out
from feedlog.diagnose.hypothesis import Hypothesis
from feedlog.errors import FeedlogError
from feedlog.profile import MachineProfile

_SCORERS: OrderedDict[str, Scorer] = OrderedDict()
KEEP = 4  # scorers a worker keeps (diagnoses x levels)


@dataclass
class PrepareItem:
    source: str
    profile: MachineProfile
    program: Any = None
    lenient: bool = False


def prepare_task(item: PrepareItem) -> Case:
    from feedlog import storage
    from feedlog.ingest import read_recording

    with storage.local_input(item.source) as local:
        rec = read_recording(local)
    rec.source = item.source
    return prepare_case(rec, item.profile, program=item.program, lenient=item.lenient)


@dataclass
class HeldOutItem:
    token: str                  # one diagnosis and level: the workers' scorer cache key
    profile: MachineProfile
    cases: list[Case]
    level: str
    min_segment_s: float | None
    model: dict[str, Any]
    hyp: Hypothesis


def _scorer(item: HeldOutItem) -> Scorer:
    scorer = _SCORERS.get(item.token)
    if scorer is None:
        scorer = Scorer(item.profile, item.cases, item.level, min_segment_s=item.min_segment_s)
        _SCORERS[item.token] = scorer
        while len(_SCORERS) > KEEP:
            _SCORERS.popitem(last=False)
    _SCORERS.move_to_end(item.token)
    return scorer


def held_out_task(item: HeldOutItem) -> HeldOut:
    return held_out(_scorer(item), item.model, item.hyp)


def held_out_on(runner, token: str, scorer: Scorer, min_segment_s: float | None
                ) -> Callable[[dict[str, Any], Sequence[Hypothesis]], list[HeldOut]]:
    """`(model, hypotheses) -> held-out results`, each hypothesis a task on `runner`."""
    def run(model: dict[str, Any], hyps: Sequence[Hypothesis]) -> list[HeldOut]:
        if len(hyps) <= 1:  # one task is cheaper here than a round trip
            return [held_out(scorer, model, h) for h in hyps]
        items = [HeldOutItem(token=token, profile=scorer.profile, cases=scorer.cases, level=scorer.level,
                             min_segment_s=min_segment_s, model=dict(model), hyp=h) for h in hyps]
        results = runner.run(held_out_task, items, desc=f"{scorer.level} fits", label=lambda i: i.hyp.key)
        failed = [r for r in results if not r.ok]
        if failed:
            raise FeedlogError(f"hypothesis fit {failed[0].label} failed: {failed[0].error}")
        return [r.value for r in results]
    return run
