"""Run the fuzz corpus through the `feedlog` command in-process and sort every run into an outcome.

    python -m tests.fuzz.runner --kind csv            # a table of outcomes for one input type
    python -m tests.fuzz.runner --kind all --jsonl    # one JSON line per run (what the tests read)

Each run gets a fresh folder holding only the case's files, calls `feedlog.cli.main(argv)` there with
stdout and stderr captured, and ends in one of:

- `ok`:          exit 0 and a sane output (strict JSON with finite numbers in range; an imported
                 recording that reads back strictly with finite values, int64 times that are not
                 INT64_MIN, dropped frames within bounds; the same result as the seed where asked)
- `clear_error`: exit 2 and exactly one line `feedlog CMD: error: ...` naming the input and where in
                 it; no output file or temporary file left behind
- `exit1_error`: the same line with exit code 1 (what feedlog printed for bad input before #19)
- `traceback`:   an exception escaped the command
- `hang`:        no answer within the time limit
- `silent`:      exit 0 with an insane output, or exit 0 where the input is known to be bad
- `unclear`:     an error that is not one line, does not name the input or the place, or left files
- `wrong_error`: an error where the input is good (a mistake that changes nothing, such as CRLF)

The process's address space is capped (`--limit-mb`), so an allocation sized by a corrupt length
field fails instead of taking the machine's memory, and shows up as a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import random
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

from tests.fuzz.cases import Case, Run

SEED = 19
KINDS = ("gcode", "mcap", "csv", "can", "config", "mtconnect")
GOOD = ("ok", "clear_error")
TIMEOUT_S = 60
MAX_TIME_S = 1e9          # longest program or recording feedlog accepts
MAX_ABS_T_NS = 2**62      # recording times stay within this, so any difference fits int64
OUTPUTS = {"out.mcap", "o.parquet"}
POSITION = re.compile(r":\d+\b|\b(line|lines|byte|frame|frames|record|message|sample|row|rows|column|chunk|"
                      r"offset|end of file)\b", re.IGNORECASE)


def build(kind: str) -> list[Case]:
    """The corpus of one input type; the same every time (seeded)."""
    from tests.fuzz import corpus_can, corpus_config, corpus_csv, corpus_gcode, corpus_mcap, corpus_mtconnect

    builders = {"gcode": corpus_gcode.build, "mcap": corpus_mcap.build, "csv": corpus_csv.build,
                "can": corpus_can.build, "config": corpus_config.build, "mtconnect": corpus_mtconnect.build}
    return builders[kind](random.Random(f"{SEED}:{kind}"))


@dataclass
class Outcome:
    kind: str
    case: str
    argv: list[str]
    expect: str
    result: str
    exit_code: int | None
    detail: str
    seconds: float


class _Hang(Exception):
    pass


def _on_alarm(signum, frame):
    raise _Hang()


def invoke(argv: list[str], folder: Path, files: dict[str, bytes]) -> tuple[int | None, str, str, BaseException | None]:
    """`feedlog ARGV` in `folder` (filled with `files`): (exit code, stdout, stderr, escaped exception)."""
    from feedlog.cli import main

    for name, data in files.items():
        (folder / name).write_bytes(data)
    out, err = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    signal.alarm(TIMEOUT_S)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code, escaped = main(argv), None
    except SystemExit as exc:  # argparse
        code, escaped = (exc.code if isinstance(exc.code, int) else 2), None
    except BaseException as exc:  # noqa: BLE001 - that is what this harness looks for
        code, escaped = None, exc
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
        os.chdir(cwd)
    return code, out.getvalue(), err.getvalue(), escaped


def _reject_constant(name: str):
    raise ValueError(f"JSON holds {name}")


def strict_json(text: str):
    """The JSON document printed, refusing NaN/Infinity and numbers beyond int64 or float64."""
    doc = json.loads(text, parse_constant=_reject_constant)

    def walk(value, where: str) -> None:
        if isinstance(value, bool) or value is None or isinstance(value, str):
            return
        if isinstance(value, int) and abs(value) >= 2**63:
            raise ValueError(f"{where} = {value} does not fit int64")
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError(f"{where} = {value}")
        if isinstance(value, dict):
            for k, v in value.items():
                walk(v, f"{where}.{k}")
        if isinstance(value, list):
            for k, v in enumerate(value):
                walk(v, f"{where}[{k}]")

    walk(doc, "$")
    return doc


def check_output(run: Run, stdout: str, folder: Path) -> tuple[str | None, object]:
    """(problem or None, a comparable digest of the result) for a run that exited 0."""
    command = run.argv[0]
    if command in ("program", "sim", "info"):
        try:
            doc = strict_json(stdout)
        except ValueError as exc:
            return f"bad JSON: {exc}", None
        if command == "program":
            if not 0 <= doc["cam_time_s"] <= MAX_TIME_S or not doc["length_mm"] >= 0:
                return f"cam_time_s {doc['cam_time_s']}, length_mm {doc['length_mm']}", None
            return None, (doc["blocks"], round(doc["length_mm"], 6), round(doc["cam_time_s"], 6))
        if command == "sim":
            if not 0 <= doc["cycle_time_s"] <= MAX_TIME_S:
                return f"cycle_time_s {doc['cycle_time_s']}", None
            return None, (doc["blocks"], doc["cycle_time_s"])
        for s in doc["streams"]:
            for key in ("t_start_ns", "t_end_ns"):
                if s[key] is not None and abs(s[key]) > MAX_ABS_T_NS:
                    return f"stream {s['name']}: {key} = {s[key]}", None
        if doc["dropped_frames"] < 0:
            return f"dropped_frames {doc['dropped_frames']}", None
        return None, sorted((s["name"], s["samples"]) for s in doc["streams"])
    if command == "import":
        return check_recording(run, folder / "out.mcap")
    return None, None


def check_recording(run: Run, path: Path) -> tuple[str | None, object]:
    import numpy as np

    from feedlog.ingest import read_recording

    if not path.is_file():
        return "exit 0 but no recording written", None
    try:
        rec = read_recording(path)
    except Exception as exc:  # noqa: BLE001
        return f"the written recording does not read back: {type(exc).__name__}: {exc}", None
    digest = []
    for name, table in rec.streams.items():
        t = table["t_ns"].to_numpy()
        if t.dtype != np.int64 or (len(t) and (np.abs(t).max() > MAX_ABS_T_NS or (np.diff(t) < 0).any())):
            return f"stream {name}: bad t_ns ({t.dtype}, {t[:3]}..)", None
        for column in table.columns[1:]:
            values = table[column].to_numpy()
            if values.dtype.kind == "f" and not np.isfinite(values).all():
                return f"stream {name}: column {column} holds NaN/inf", None
        digest.append((name, len(t), int(t.sum()) if len(t) else 0,
                       tuple(round(float(np.asarray(table[c], dtype=float).sum()), 3) for c in table.columns[1:])))
    if rec.dropped_frames < 0:
        return f"dropped_frames {rec.dropped_frames}", None
    if run.max_dropped_ratio is not None:
        frames = int(rec.metadata.get("frames", "0") or 0)
        if rec.dropped_frames > run.max_dropped_ratio * max(frames, 1):
            return f"dropped_frames {rec.dropped_frames} of {frames} frames", None
    return None, sorted(digest)


def classify(case: Case, run: Run, code: int | None, stdout: str, stderr: str, escaped: BaseException | None,
             folder: Path) -> tuple[str, str]:
    if isinstance(escaped, _Hang):
        return "hang", f"no answer within {TIMEOUT_S} s"
    if escaped is not None:
        return "traceback", f"{type(escaped).__name__}: {str(escaped)[:300]}"
    left = sorted(set(os.listdir(folder)) - set(case.files) - (OUTPUTS if code == 0 else set()))
    if code == 0:
        problem, _ = check_output(run, stdout, folder)
        if problem:
            return "silent", problem
        if run.expect == "error":
            return "silent", "exit 0 on input known to be bad"
        if left:
            return "unclear", f"left files behind: {left}"
        return "ok", ""
    lines = stderr.strip().splitlines()
    message = lines[0] if lines else ""
    prefix = f"feedlog {run.argv[0]}: error: "
    if len(lines) != 1 or not message.startswith(prefix):
        return "unclear", f"exit {code}, stderr {stderr.strip()[:300]!r}"
    if case.input not in message:
        return "unclear", f"does not name {case.input!r}: {message[:300]}"
    if case.located and not POSITION.search(message[len(prefix):].replace(case.input, "")):
        return "unclear", f"does not say where: {message[:300]}"
    if left:
        return "unclear", f"left files behind after the error: {left}"
    if run.expect == "ok":
        return "wrong_error", message[:300]
    if code == 1:
        return "exit1_error", message[:300]
    if code != 2:
        return "unclear", f"exit {code}: {message[:300]}"
    return "clear_error", message[:300]


def run_case(case: Case, scratch: Path) -> list[Outcome]:
    outcomes = []
    for k, run in enumerate(case.runs):
        folder = Path(tempfile.mkdtemp(prefix=f"run{k}-", dir=scratch))
        start = time.perf_counter()
        code, stdout, stderr, escaped = invoke(run.argv, folder, case.files)
        result, detail = classify(case, run, code, stdout, stderr, escaped, folder)
        if result == "ok" and run.same_as_seed:
            result, detail = _compare_with_seed(case, run, folder, stdout)
        outcomes.append(Outcome(case.kind, case.name, run.argv, run.expect, result, code, detail,
                                round(time.perf_counter() - start, 3)))
        shutil.rmtree(folder, ignore_errors=True)
    return outcomes


def _compare_with_seed(case: Case, run: Run, folder: Path, stdout: str) -> tuple[str, str]:
    _, mine = check_output(run, stdout, folder)
    seed_folder = Path(tempfile.mkdtemp(prefix="seed-", dir=folder.parent))
    code, seed_out, seed_err, escaped = invoke(run.argv, seed_folder, case.seed)
    _, theirs = check_output(run, seed_out, seed_folder) if code == 0 else (None, None)
    shutil.rmtree(seed_folder, ignore_errors=True)
    if code != 0 or escaped is not None:
        return "unclear", f"the seed itself fails: {seed_err.strip()[:200]} {escaped!r}"
    if mine != theirs:
        return "silent", f"differs from the seed: {str(mine)[:200]} vs {str(theirs)[:200]}"
    return "ok", ""


def limit_memory(extra_mb: int) -> None:
    """Cap the address space at what the process holds now plus `extra_mb`."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[0])
    limit = pages * os.sysconf("SC_PAGE_SIZE") + extra_mb * 2**20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", default="all", choices=(*KINDS, "all"))
    parser.add_argument("--jsonl", action="store_true", help="one JSON line per run")
    parser.add_argument("--limit-mb", type=int, default=3000, help="address space allowed beyond the start-up")
    parser.add_argument("--only", help="run only cases whose name contains this")
    args = parser.parse_args(argv)
    import feedlog.cli
    import feedlog.ingest
    import feedlog.sim
    import feedlog.toolpath

    kinds = KINDS if args.kind == "all" else (args.kind,)
    corpora = {kind: build(kind) for kind in kinds}
    if "config" in kinds:
        import feedlog.train.checkpoint  # noqa: F401 (torch)
    limit_memory(args.limit_mb)
    outcomes: list[Outcome] = []
    with tempfile.TemporaryDirectory(prefix="feedlog-fuzz-") as scratch:
        for kind, cases in corpora.items():
            for case in cases:
                if args.only and args.only not in case.name:
                    continue
                for outcome in run_case(case, Path(scratch)):
                    outcomes.append(outcome)
                    if args.jsonl:
                        print(json.dumps(asdict(outcome)), flush=True)
                    elif outcome.result not in GOOD:
                        print(f"{outcome.result:<12} {outcome.case:<48} {' '.join(outcome.argv)[:60]}\n"
                              f"{'':13}{outcome.detail}", flush=True)
    if not args.jsonl:
        print(summary(corpora, outcomes))
        print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    return 0


def summary(corpora: dict[str, list[Case]], outcomes: list[Outcome]) -> str:
    columns = ("ok", "clear_error", "exit1_error", "traceback", "hang", "silent", "unclear", "wrong_error")
    lines = [f"{'kind':<8} {'cases':>6} {'runs':>6} " + " ".join(f"{c:>11}" for c in columns)]
    for kind, cases in corpora.items():
        counts = Counter(o.result for o in outcomes if o.kind == kind)
        lines.append(f"{kind:<8} {len(cases):>6} {sum(counts.values()):>6} " + " ".join(f"{counts[c]:>11}" for c in columns))
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
