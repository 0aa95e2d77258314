"""Plots drawn in a worker process (viz/plot_worker.py): the same PNGs as drawn in the caller, results in
submission order, a worker's error raised to the caller, and no backlog beyond `in_flight`."""

from __future__ import annotations

import pytest
from tests.viz import synthetic as syn

from feedlog.viz.plot_worker import PlotWorker
from feedlog.viz.prepare import ViewInputs, prepare_view


def _data(name: str):
    series, blocks = syn.sim_result()
    return prepare_view(ViewInputs(syn.recording(), name=name, program_blocks=syn.program_blocks(),
                                   sim_series=series, sim_blocks=blocks))


def test_a_worker_draws_what_the_caller_draws(tmp_path):
    datas = [_data(f"r{i}") for i in range(4)]
    with PlotWorker(0) as here:
        for d in datas:
            here.submit(d.name, d, tmp_path / "here", stem=d.name, kinds=("feed", "blocks"))
        local = here.results()
    with PlotWorker(1, in_flight=2) as there:
        for d in datas:
            there.submit(d.name, d, tmp_path / "there", stem=d.name, kinds=("feed", "blocks"))
            assert len(there.pending) <= 2
        remote = there.results()
    assert list(remote) == [d.name for d in datas] == list(local)
    for name in local:
        assert sorted(remote[name]) == ["blocks", "feed"]
        for kind, path in remote[name].items():   # Agg draws the same pixels in either process
            assert path.parent == tmp_path / "there" and path.read_bytes() == local[name][kind].read_bytes()


def test_a_plot_that_fails_in_the_worker_fails_the_caller(tmp_path):
    with PlotWorker(1) as worker:
        worker.submit("bad", _data("bad"), tmp_path, stem="bad", kinds=("feeds",))
        with pytest.raises(ValueError, match="unknown plot kinds"):
            worker.results()
