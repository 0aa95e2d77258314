"""A real Dask cluster for tests: `dask scheduler` and `dask worker` processes on 127.0.0.1.

Ports are chosen by the scheduler itself (`--port 0`, address read back from its scheduler file), so
parallel test runs never collide. Workers run in their own directory (not the client's) and are
started in their own process group, so a test can kill one like a lost host (`kill_worker`).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

START_TIMEOUT_S = 120.0  # generous: a loaded 2-core machine imports pandas/dask slowly


@contextmanager
def dask_cluster(tmp: Path, *, workers: int = 2):
    """Yields (address, [worker Popen]); everything is stopped afterwards."""
    tmp.mkdir(parents=True, exist_ok=True)
    file = tmp / "scheduler.json"
    logs = tmp / "logs"
    logs.mkdir(exist_ok=True)
    procs: list[subprocess.Popen] = []

    def start(args: list[str], name: str, cwd: Path) -> subprocess.Popen:
        cwd.mkdir(parents=True, exist_ok=True)
        out = open(logs / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        proc = subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=cwd, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)
        procs.append(proc)
        return proc

    try:
        start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(file)],
              "scheduler", tmp / "scheduler")
        address = _wait_address(file, procs[0], logs / "scheduler.log")
        started = [start(["worker", address, "--nthreads", "1", "--nworkers", "1", "--memory-limit", "0",
                          "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{i}",
                          "--local-directory", str(tmp / f"w{i}")],
                         f"worker{i}", tmp / f"w{i}") for i in range(workers)]
        wait_for_workers(address, workers)
        yield address, started
    finally:
        for proc in reversed(procs):
            stop(proc)


def _wait_address(file: Path, proc: subprocess.Popen, log: Path) -> str:
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"dask scheduler exited: {log.read_text()[-2000:]}")
        try:
            return json.loads(file.read_text())["address"]
        except (OSError, ValueError, KeyError):
            time.sleep(0.2)
    raise RuntimeError(f"dask scheduler did not start within {START_TIMEOUT_S} s")


def wait_for_workers(address: str, n: int) -> None:
    from distributed import Client

    with Client(address, timeout=START_TIMEOUT_S) as client:
        client.wait_for_workers(n, timeout=START_TIMEOUT_S)


def stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=20)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            kill_worker(proc)
    if proc.stdout:
        proc.stdout.close()


def kill_worker(proc: subprocess.Popen) -> None:
    """SIGKILL the worker's whole process group (nanny and worker): a host lost mid-task."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=20)


def feedlog(*args: str, cwd: Path, timeout: float = 600.0) -> subprocess.CompletedProcess:
    """`python -m feedlog ARGS` from `cwd`, FEEDLOG_SCHEDULER cleared."""
    env = {k: v for k, v in os.environ.items() if k != "FEEDLOG_SCHEDULER"}
    return subprocess.run([sys.executable, "-m", "feedlog", *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)


def same_outputs(a: Path, b: Path) -> list[str]:
    """Files that differ between two output trees (Parquet byte for byte; report.json without its timings)."""
    diffs = []
    names = sorted({p.relative_to(a).as_posix() for p in a.rglob("*") if p.is_file()}
                   | {p.relative_to(b).as_posix() for p in b.rglob("*") if p.is_file()})
    for name in names:
        pa, pb = a / name, b / name
        if not (pa.is_file() and pb.is_file()):
            diffs.append(f"{name}: only in {'first' if pa.is_file() else 'second'}")
        elif name.endswith("report.json"):
            ja, jb = (json.loads(p.read_text()) for p in (pa, pb))
            ja.pop("timings_s", None), jb.pop("timings_s", None)
            if ja != jb:
                diffs.append(name)
        elif pa.read_bytes() != pb.read_bytes():
            diffs.append(name)
    return diffs
