"""LinuxCNC recordings for the integration tests: several sessions at once, each recording made once.

A recording waits on LinuxCNC's servo thread, not on the CPU. Measured on this 2-core host with the
densest bundled program (longdense_002, 2.883 s of motion; one session alone 6.5-7.2 s of wall time):
with the host's load average at 6, 4 isolated sessions at once took 6.3 s and 8 took 7.2 s, every one
2.883 s with no sampler overrun; at a load average of 18 (other work on the host), 4 at once still gave
2.883 s each (8.0 s), but 8 at once gave 2.884 or 2.885 s in 3 of 8 (LinuxCNC's task, starved of CPU,
fed the short blocks late) and 16 at once in at least 2 of 16. So the fixtures run up to 4 sessions at once
(private namespaces, root only; one at a time otherwise; FEEDLOG_TEST_LINUXCNC_SESSIONS overrides),
and a session recorded once in a test run serves every test that asks for the same machine, program
and dial: `record_all` keys each job by the INI's text, its HAL files, the program's bytes and the
recorder options, not by path.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from feedlog.ingest.linuxcnc import record_linuxcnc
from feedlog.ingest.linuxcnc_session import MachineIni, isolation_available
from feedlog.profile import shipped_profiles

ROOT = Path(__file__).resolve().parents[2]
# how many LinuxCNC sessions run at once (isolated sessions only); FEEDLOG_TEST_LINUXCNC_SESSIONS overrides
SESSIONS = int(os.environ.get("FEEDLOG_TEST_LINUXCNC_SESSIONS", "4"))


@dataclass(frozen=True)
class Job:
    """One program run on one machine, written to `out` (its recorder options as record_linuxcnc's)."""

    ini: Path
    program: Path
    out: Path
    options: dict = field(default_factory=dict, hash=False, compare=False)

    def key(self) -> str:
        """What makes two jobs the same recording: the machine's files, the program and the options."""
        digest = hashlib.sha256()
        ini = MachineIni.read(self.ini)
        for part in (ini.text.encode(), *(p.read_bytes() for p in ini.hal_files()), self.program.read_bytes(),
                     repr(sorted(self.options.items())).encode()):
            digest.update(len(part).to_bytes(8, "little") + part)
        return digest.hexdigest()


_DONE: dict[str, tuple[Path, dict]] = {}   # job key -> (recording, summary), for the whole test run


def isolated() -> bool:
    return isolation_available() is None


def expected_s(program: Path) -> float:
    """The cycle time the manifest gives the program's bundled recording (0 for a program it lacks)."""
    manifest = tomllib.loads((ROOT / "recordings" / "manifest.toml").read_text())
    times = {r["program"].split("/")[-1]: float(r.get("cycle_time_s", 0.0)) for r in manifest["recording"]}
    return times.get(program.name, 0.0)


def record_all(jobs: list[Job], *, timeout_s: float = 120.0) -> list[dict]:
    """Record every job (up to SESSIONS at once when isolated) and return their summaries in order.

    A job recorded before in this test run is copied to its `out`, not run again. Each session must end
    `complete`; the longest programs start first so that the batch ends soonest.
    """
    isolate = isolated()
    keys = [job.key() for job in jobs]
    todo: dict[str, Job] = {}
    for key, job in zip(keys, jobs):
        if key not in _DONE or not _DONE[key][0].is_file():
            todo.setdefault(key, job)

    def run(item: tuple[str, Job]) -> tuple[str, Path, dict]:
        key, job = item
        job.out.parent.mkdir(parents=True, exist_ok=True)
        summary = record_linuxcnc(job.ini, job.program, job.out, isolate=isolate, timeout_s=timeout_s, **job.options)
        assert summary["status"] == "complete", summary
        return key, job.out, summary

    order = sorted(todo.items(), key=lambda item: -expected_s(item[1].program))
    # the shipped profiles' registry loads on first use, and that load is not thread-safe: a second thread
    # arriving while the first lists the profiles finds none ("unknown machine profile 'linuxcnc-xyzac';
    # shipped: ", seen once with 4 sessions starting at once). Loaded here, before the threads.
    shipped_profiles()
    with ThreadPoolExecutor(max(1, min(SESSIONS if isolate else 1, len(order)))) as pool:
        for key, out, summary in pool.map(run, order):
            _DONE[key] = (out, summary)
    summaries = []
    for key, job in zip(keys, jobs):
        made, summary = _DONE[key]
        if made != job.out:
            job.out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(made, job.out)
        summaries.append(dict(summary, out=str(job.out)))
    return summaries
