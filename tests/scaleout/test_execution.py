"""feedlog.execution: one contract on every backend (order, per-item errors, bugs, lost workers)."""

from __future__ import annotations

import cloudpickle
import pytest

from feedlog.errors import FeedlogError
from feedlog.execution import ENV_SCHEDULER, TaskRunner, choose, run_tasks
from tests.scaleout import tasks

cloudpickle.register_pickle_by_value(tasks)  # a LocalCluster's workers do not have tests/ on their path


def test_choose_backend(monkeypatch):
    monkeypatch.delenv(ENV_SCHEDULER, raising=False)
    assert choose(None, None) == ("processes", None, None)
    assert choose(1, None) == ("serial", 1, None)
    assert choose(None, "tcp://h:8786") == ("dask", None, "tcp://h:8786")
    assert choose(3, "local") == ("dask", 3, "local")
    monkeypatch.setenv(ENV_SCHEDULER, "tcp://env:8786")
    assert choose(None, None) == ("dask", None, "tcp://env:8786")
    assert choose(2, None) == ("processes", 2, None)          # the command line beats the environment
    assert choose(None, "none") == ("processes", None, None)
    with pytest.raises(FeedlogError, match="--jobs 2 and --scheduler tcp://h:8786 both given"):
        choose(2, "tcp://h:8786")
    with pytest.raises(FeedlogError, match="--jobs must be >= 1, got 0"):
        choose(0, None)


@pytest.mark.parametrize("jobs", [1, 2])
def test_local_results_in_order_with_per_item_errors(jobs):
    items = [3, -1, 4, 0, -5, 2]
    results = run_tasks(tasks.square, items, jobs=jobs, progress=False)
    assert [r.label for r in results] == [str(i) for i in items]
    assert [r.value for r in results] == [9, None, 16, 0, None, 4]
    assert [r.error for r in results if not r.ok] == ["item -1 is negative", "item -5 is negative"]
    assert all(r.task_s >= 0 for r in results)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_bug_propagates(jobs):
    with pytest.raises(ValueError, match="unlucky"):
        run_tasks(tasks.square, [1, 13, 2], jobs=jobs, progress=False)


def test_a_dead_worker_process_is_replaced_and_its_task_rerun(tmp_path):
    marker = str(tmp_path / "died")
    results = run_tasks(tasks.die_once, [(marker, v) for v in range(5)], jobs=2, progress=False)
    assert (tmp_path / "died").exists()  # it did die once
    assert [r.value for r in results] == [0, 10, 20, 30, 40] and all(r.ok for r in results)


@pytest.mark.parametrize("retries", [0, 2])
def test_a_task_that_always_kills_its_worker_is_reported_alone(retries):
    results = run_tasks(tasks.slow_or_die, [0, 1, 2, 3, 4, 5], jobs=2, progress=False, retries=retries)
    assert not results[2].ok and f"worker process died {retries + 1} times" in results[2].error
    # its neighbours (running beside it when it died, or queued) ran again and finished
    assert [r.value for r in results] == [0, 10, None, 30, 40, 50]


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_local_dask_cluster_same_contract(tmp_path):
    dask = pytest.importorskip("dask")
    logged: list[str] = []
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with TaskRunner(scheduler="local", jobs=2, progress=False, log=logged.append) as runner:
            results = runner.run(tasks.square, [3, -1, 4, 2], desc="square")
            assert [r.value for r in results] == [9, None, 16, 4]
            assert results[1].error == "item -1 is negative"
            with pytest.raises(ValueError, match="unlucky"):
                runner.run(tasks.square, [1, 13], desc="square")
            died = runner.run(tasks.die_always, [0, 2, 3], desc="die")  # the same cluster, a third call
    assert "Dask: 2 worker(s)" in logged[0] and "dashboard" in logged[0]
    assert len(logged) == 1
    assert [r.ok for r in died] == [True, False, True] and "worker was lost" in died[1].error
    assert died[0].value == 0 and died[2].value == 30


def test_each_task_is_reported_as_it_ends_not_when_the_batch_does():
    """`on_done` runs in this process as each task ends: the quick task's call comes while the slow one runs."""
    import time

    calls = []
    with TaskRunner(jobs=2, progress=False) as runner:
        results = runner.run(time.sleep, [1.5, 0.0], on_done=lambda k, i, r: calls.append((k, i, r.ok, time.monotonic())))
        returned = time.monotonic()
    assert [r.ok for r in results] == [True, True]
    assert [(k, i, ok) for k, i, ok, _ in calls] == [(1, 1, True), (2, 0, True)]
    assert calls[0][3] < returned - 1.0


def test_serial_runs_report_each_task_in_order():
    seen = []
    with TaskRunner(jobs=1, progress=False) as runner:
        runner.run(tasks.square, [2, -1, 3], on_done=lambda k, i, r: seen.append((k, i, r.value)))
    assert seen == [(1, 0, 4), (2, 1, None), (3, 2, 9)]
