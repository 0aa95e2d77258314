"""Where a command's many independent tasks run: here, in local worker processes, or on a Dask cluster.

Every command that works on many inputs (align, sim over several programs, train's data preparation,
demo, ...) hands its per-input function to `run_tasks`; the stage never knows which backend ran it.

    results = run_tasks(align_one, tasks, jobs=2, desc="align")                  # 2 local processes
    results = run_tasks(align_one, tasks, scheduler="tcp://10.0.0.5:8786")       # a Dask cluster
    [(r.label, r.ok, r.value, r.error) for r in results]                         # input order

    with task_runner(scheduler="local", jobs=4) as runner:                       # one cluster, many calls
        a = runner.run(prepare, runs, desc="prepare")
        b = runner.run(simulate_one, programs, desc="sim")

Backends (`BACKENDS`, chosen by `jobs` and `scheduler`):
- `serial`: no scheduler and `jobs` 1 (or a single item): in this process, in order.
- `processes`: no scheduler, `jobs` > 1 (None: all cores): `concurrent.futures.ProcessPoolExecutor`.
- `dask`: a `dask.distributed.Client` to `scheduler`: an address (`tcp://HOST:8786`, a running
  `dask scheduler`), a scheduler file (`*.json`, written by `dask scheduler --scheduler-file`, as on
  HPC with dask-jobqueue), or `local` (a `LocalCluster` of `jobs` single-threaded worker processes for
  the run). The Dask dashboard's address is logged. We never schedule anything ourselves.
`FEEDLOG_SCHEDULER` in the environment stands for `scheduler` when the command line gives neither a
scheduler nor `jobs` (the command line beats the environment); `none` there or on the command line
means no cluster.

Contract for `fn` (the lead of `feedlog diagnose` and anyone else plugging in):
- a module-level (picklable) function of one item; items and return values picklable and small
  (send paths or URLs, not recordings; return summaries, not tables);
- items carry absolute paths or fsspec URLs: a worker may run on another host in another directory;
- safe to run twice on the same item (a task whose worker died is run again): write outputs under a
  temporary name and rename them into place (`feedlog.storage.publish_dir`), never append.

Failures, per item:
- a `FeedlogError` raised by `fn` makes that item's result `ok=False` with the error's message; the
  other items go on. Bad input stays bad, so it is not retried.
- a lost worker (process killed, host gone): the task runs again; with local processes alone in a
  pool (so that its neighbours are not blamed), reported after `retries` + 1 deaths alone; on Dask the scheduler re-runs it itself, up to its `distributed.scheduler.allowed-failures`
  (default 3), and then reports `KilledWorker`. Either way the item ends `ok=False` saying so.
- any other exception is a bug: unfinished tasks are cancelled and it is raised here (on Dask with the
  worker's traceback).
"""

from __future__ import annotations

import importlib.metadata
import os
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from feedlog.errors import FeedlogError

T = TypeVar("T")
R = TypeVar("R")

ENV_SCHEDULER = "FEEDLOG_SCHEDULER"
LOCAL = "local"          # --scheduler local: a LocalCluster for the run
NO_SCHEDULER = "none"    # --scheduler none: ignore FEEDLOG_SCHEDULER
WORKER_WAIT_S = 60.0     # how long a client waits for the first worker to join its scheduler
CONNECT_TIMEOUT_S = 30.0


@dataclass
class TaskResult(Generic[R]):
    """One item's outcome: `value` when `ok`, else `error` (our error's message, or why the worker was lost)."""

    label: str
    ok: bool
    value: R | None = None
    error: str | None = None
    task_s: float = 0.0        # time inside `fn` on the worker (0 when the worker was lost)
    exit_code: int = 0         # of a failed item: the error's (2 bad input, 1 an output that could not be written)


def _call(fn: Callable[[Any], Any], item: Any) -> tuple[bool, Any, float]:
    """Runs on the worker: our errors become data (not retried, not a crash); bugs propagate."""
    start = time.perf_counter()
    try:
        value = fn(item)
    except FeedlogError as exc:
        return False, (str(exc) or type(exc).__name__, exc.exit_code), time.perf_counter() - start
    return True, value, time.perf_counter() - start


def _result(label: str, outcome: tuple[bool, Any, float]) -> TaskResult:
    ok, value, seconds = outcome
    if ok:
        return TaskResult(label, True, value=value, task_s=seconds)
    message, code = value
    return TaskResult(label, False, error=message, task_s=seconds, exit_code=code)


def add_arguments(parser: Any, *, jobs_help: str = "local worker processes (default: all cores)") -> None:
    """`-j/--jobs` and `--scheduler`, the same on every command that runs many tasks."""
    parser.add_argument("--jobs", "-j", type=int, default=None, help=jobs_help)
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help=f"run the tasks on a Dask cluster: tcp://HOST:PORT, a scheduler file (.json), "
                             f"'{LOCAL}' (a local Dask cluster of --jobs workers) or '{NO_SCHEDULER}' "
                             f"(default: ${ENV_SCHEDULER} when set and --jobs is not given)")


def choose(jobs: int | None, scheduler: str | None) -> tuple[str, int | None, str | None]:
    """(backend name, jobs, scheduler) after the environment and the checks."""
    if jobs is not None and jobs < 1:
        raise FeedlogError(f"--jobs must be >= 1, got {jobs}")
    if scheduler is None and jobs is None:
        scheduler = os.environ.get(ENV_SCHEDULER) or None
    if scheduler is not None and scheduler.strip().lower() in ("", NO_SCHEDULER):
        scheduler = None
    if scheduler is None:
        return ("serial" if jobs == 1 else "processes"), jobs, None
    if jobs is not None and scheduler != LOCAL:
        raise FeedlogError(f"--jobs {jobs} and --scheduler {scheduler} both given: the cluster's workers set the "
                           f"parallelism (use --scheduler {LOCAL} --jobs {jobs} for a local Dask cluster)")
    return "dask", jobs, scheduler


class _Serial:
    """In this process, in order."""

    def __init__(self, **_: Any) -> None:
        pass

    def map(self, fn, items, labels, done, desc) -> list[TaskResult]:
        out = []
        for i, (item, label) in enumerate(zip(items, labels)):
            out.append(_result(label, _call(fn, item)))
            done(i, out[-1])
        return out

    def close(self) -> None:
        pass


def _call_marked(fn: Callable[[Any], Any], item: Any, mark: str) -> tuple[bool, Any, float]:
    Path(mark).touch()  # this task started: if its process dies now, the task is a suspect
    return _call(fn, item)


class _Processes:
    """Local worker processes. When one dies the pool breaks: tasks that had started are suspects and run
    again, each in a pool of its own (so a task that kills its worker is told from its neighbours); one
    whose process dies `retries` + 1 times alone is reported. Tasks that had not started run again in a
    fresh pool."""

    def __init__(self, *, jobs: int | None, retries: int, **_: Any) -> None:
        self.jobs = jobs or os.cpu_count() or 1
        self.retries = retries

    def map(self, fn, items, labels, done, desc) -> list[TaskResult]:
        results: dict[int, TaskResult] = {}
        suspects: set[int] = set()              # had started in a pool that broke
        deaths = dict.fromkeys(range(len(items)), 0)   # its process died while it ran alone
        pending = list(range(len(items)))
        with tempfile.TemporaryDirectory(prefix="feedlog-tasks-") as marks:
            while pending:
                broken = self._pool(fn, items, [i for i in pending if i not in suspects], self.jobs, marks,
                                    labels, results, done)
                for i in (i for i in pending if i in suspects):
                    for j, started in self._pool(fn, items, [i], 1, marks, labels, results, done):
                        deaths[j] += started
                        broken.append((j, False))
                pending = []
                for i, started in broken:
                    if started:
                        suspects.add(i)
                    if deaths[i] > self.retries:
                        results[i] = TaskResult(labels[i], False, exit_code=1, error=f"worker process died {deaths[i]} times while "
                                                                        "running it alone (killed? out of memory?)")
                        done(i, results[i])
                    else:
                        pending.append(i)
        return [results[i] for i in range(len(items))]

    @staticmethod
    def _pool(fn, items, indices, jobs, marks, labels, results, done) -> list[tuple[int, bool]]:
        """Run `indices` in one pool; (index, had started) of those lost to a broken pool."""
        if not indices:
            return []
        broken = []
        mark = {i: os.path.join(marks, str(i)) for i in indices}
        for path in mark.values():
            Path(path).unlink(missing_ok=True)
        with ProcessPoolExecutor(max_workers=min(jobs, len(indices))) as pool:
            futures = {pool.submit(_call_marked, fn, items[i], mark[i]): i for i in indices}
            try:
                for fut in as_completed(futures):
                    i = futures[fut]
                    try:
                        results[i] = _result(labels[i], fut.result())
                        done(i, results[i])
                    except BrokenProcessPool:
                        broken.append((i, os.path.exists(mark[i])))
            except BaseException:
                for fut in futures:
                    fut.cancel()
                raise
        return broken

    def close(self) -> None:
        pass


class _Dask:
    """A dask.distributed Client: to a running scheduler, from a scheduler file, or to a LocalCluster."""

    def __init__(self, *, scheduler: str, jobs: int | None, log: Callable[[str], None], **_: Any) -> None:
        try:
            from distributed import Client, LocalCluster  # heavy; only for cluster runs
        except ImportError as exc:
            raise FeedlogError(f"--scheduler needs dask.distributed ({exc}); pip install 'dask[distributed]'") \
                from None
        self.cluster = None
        self.scheduler = scheduler
        try:
            if scheduler == LOCAL:
                import logging

                self.cluster = LocalCluster(n_workers=jobs or os.cpu_count() or 1, threads_per_worker=1,
                                            processes=True, dashboard_address=":0", silence_logs=logging.ERROR)
                self.client = Client(self.cluster)
            elif scheduler.endswith(".json") and Path(scheduler).is_file():
                self.client = Client(scheduler_file=scheduler, timeout=CONNECT_TIMEOUT_S)
            else:
                self.client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            self.close()
            raise FeedlogError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        try:
            self.client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        except TimeoutError:
            self.close()
            raise FeedlogError(f"no Dask worker joined the scheduler at {scheduler} within {WORKER_WAIT_S:.0f} s; "
                               f"start some with `dask worker {scheduler}`") from None
        self._check_versions()
        workers = self.client.scheduler_info().get("workers", {})
        threads = sum(int(w.get("nthreads", 1)) for w in workers.values())
        log(f"Dask: {len(workers)} worker(s), {threads} thread(s) at {self.client.scheduler.address}; "
            f"dashboard {self.client.dashboard_link}")

    def _check_versions(self) -> None:
        """Every worker must run our version of feedlog (tasks are pickled by reference to its functions)."""
        try:
            ours = importlib.metadata.version("feedlog")
        except importlib.metadata.PackageNotFoundError:
            return  # run from a source tree, not installed: nothing to compare with
        theirs = self.client.run(importlib.metadata.version, "feedlog", on_error="return")
        bad = {w: v for w, v in theirs.items() if v != ours}
        if bad:
            worker, version = next(iter(bad.items()))
            what = f"has feedlog {version}" if isinstance(version, str) else f"cannot import feedlog ({version!r})"
            self.close()
            raise FeedlogError(f"Dask worker {worker} {what}, this client has {ours}: install the same feedlog on "
                               f"every worker ({len(bad)} of {len(theirs)} differ)")

    def map(self, fn, items, labels, done, desc) -> list[TaskResult]:
        from distributed import as_completed as completed
        from distributed import KilledWorker

        token = uuid.uuid4().hex[:8]
        futures = {self.client.submit(_call, fn, item, key=f"feedlog-{desc}-{i}-{token}"): i
                   for i, item in enumerate(items)}
        results: dict[int, TaskResult] = {}
        try:
            for fut in completed(futures):
                i = futures[fut]
                if fut.status == "finished":
                    results[i] = _result(labels[i], fut.result())
                else:
                    exc = fut.exception() if fut.status == "error" else None
                    if exc is not None and not isinstance(exc, KilledWorker):
                        fut.result()  # a bug in `fn`: raise it here with the worker's traceback
                    why = (f"its worker was lost too often ({exc})" if exc is not None
                           else f"task {fut.status} (scheduler restarted or connection lost?)")
                    results[i] = TaskResult(labels[i], False, error=why, exit_code=1)
                done(i, results[i])
        finally:
            self.client.cancel([f for f in futures if not f.done()])
        return [results[i] for i in range(len(items))]

    def close(self) -> None:
        for thing in (getattr(self, "client", None), self.cluster):
            if thing is not None:
                thing.close()


BACKENDS = {"serial": _Serial, "processes": _Processes, "dask": _Dask}


class TaskRunner:
    """An open backend; `run` may be called many times (one Dask client or cluster for all of them)."""

    def __init__(self, *, jobs: int | None = None, scheduler: str | None = None, progress: bool = True,
                 retries: int = 2, log: Callable[[str], None] | None = None) -> None:
        self.name, self.jobs, self.scheduler = choose(jobs, scheduler)
        self.progress = progress
        self.retries = retries
        self.log = log or (lambda msg: print(msg, file=sys.stderr))
        self._backend: Any = None

    def _open(self, n_items: int):
        if self._backend is None:
            if self.name == "processes" and n_items == 1:
                return _Serial()  # one item: no pool for it (a later call may still open one)
            self._backend = BACKENDS[self.name](jobs=self.jobs, scheduler=self.scheduler, retries=self.retries,
                                                log=self.log)
        return self._backend

    def run(self, fn: Callable[[T], R], items: Sequence[T], *, desc: str = "tasks",
            label: Callable[[T], str] = str,
            on_done: Callable[[int, int, TaskResult[R]], None] | None = None) -> list[TaskResult[R]]:
        """`fn(item)` for every item; results in input order (see the module docstring for failures).
        `on_done(k, index, result)` is called as each task ends, the k-th to end (1-based), in this process."""
        from tqdm import tqdm

        items = list(items)
        labels = [label(item) for item in items]
        if not items:
            return []
        backend = self._open(len(items))
        # disable=None: no bar when not a terminal
        with tqdm(total=len(items), desc=desc, unit="task", disable=None if self.progress else True) as bar:
            ended = 0

            def done(i: int, result: TaskResult) -> None:
                nonlocal ended
                ended += 1
                bar.update()
                if on_done is not None:
                    on_done(ended, i, result)

            return backend.map(fn, items, labels, done, desc)

    def close(self) -> None:
        if self._backend is not None:
            self._backend.close()
            self._backend = None

    def __enter__(self) -> TaskRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextmanager
def task_runner(**options: Any) -> Iterator[TaskRunner]:
    """`TaskRunner(**options)` closed on exit (the LocalCluster stopped, the client disconnected)."""
    runner = TaskRunner(**options)
    try:
        yield runner
    finally:
        runner.close()


def run_tasks(fn: Callable[[T], R], items: Sequence[T], *, jobs: int | None = None, scheduler: str | None = None,
              desc: str = "tasks", label: Callable[[T], str] = str, progress: bool = True, retries: int = 2,
              log: Callable[[str], None] | None = None) -> list[TaskResult[R]]:
    """Run `fn` on every item with the backend `jobs`/`scheduler` choose; results in input order."""
    with task_runner(jobs=jobs, scheduler=scheduler, progress=progress, retries=retries, log=log) as runner:
        return runner.run(fn, items, desc=desc, label=label)


def failed(results: Sequence[TaskResult]) -> list[TaskResult]:
    return [r for r in results if not r.ok]
