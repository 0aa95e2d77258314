"""train's data preparation (reading aligned folders, the hybrid's simulations) through feedlog.execution:
the same tables as one by one."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from feedlog.align.batch import align_many
from feedlog.execution import TaskRunner
from feedlog.train import load_many
from feedlog.train.evaluate import _with_sim
from feedlog.train.model_hybrid import SIM_COLUMN

ROOT = Path(__file__).resolve().parents[2]
NAMES = ["test_p001", "mix_001", "mix5ax_000", "circle_f1000_p01"]


@pytest.fixture(scope="module")
def aligned(tmp_path_factory):
    out = tmp_path_factory.mktemp("aligned")
    items = align_many([ROOT / "recordings" / f"{n}.mcap" for n in NAMES], out, jobs=1, progress=False)
    assert all(i.ok for i in items)
    return out


def test_load_many_on_processes_equals_serial(aligned):
    serial = load_many([aligned], test=["mix_001"])
    with TaskRunner(jobs=2, progress=False) as runner:
        parallel = load_many([aligned], test=["mix_001"], runner=runner)
    assert [t.name for t in parallel] == [t.name for t in serial] == sorted(NAMES)
    for a, b in zip(serial, parallel):
        assert (a.split, a.program, a.metadata, a.profile) == (b.split, b.program, b.metadata, b.profile)
        assert a.program_text == b.program_text is not None
        pd.testing.assert_frame_equal(a.blocks, b.blocks)
    assert [t.split for t in parallel if t.name == "mix_001"] == ["test"]


def test_hybrid_simulations_on_processes_equal_serial(aligned):
    tables = load_many([aligned])
    logged: list[str] = []
    serial = _with_sim(tables, logged.append, TaskRunner(jobs=1, progress=False))
    with TaskRunner(jobs=2, progress=False) as runner:
        parallel = _with_sim(tables, logged.append, runner)
    assert logged == []
    for a, b in zip(serial, parallel):
        assert a.blocks[SIM_COLUMN].sum() > 0
        pd.testing.assert_series_equal(a.blocks[SIM_COLUMN], b.blocks[SIM_COLUMN])
