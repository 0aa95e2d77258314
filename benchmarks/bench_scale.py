"""Production-size programs (issue #22): time, blocks/s, peak RSS and bytes per block, 10k to 10M blocks.

The programs are generated here (deterministic, written to --workdir once and reused) to look like
mould finishing from CAM:

- 3-axis (linuxcnc-xyz): zig-zag raster passes over a freeform surface z = f(x, y), G64 P0.01 Q0.005,
  F3000, chords of 0.15-0.6 mm along a pass, a step-over at each pass end and a G0 retract and
  approach every 20 passes.
- 5-axis (linuxcnc-xyzac): the same raster with A tilting between -35 and -5 deg and C turning with
  the surface normal's direction.

Each case runs `feedlog` in its own process (os.wait4 gives that process's peak RSS):

- program:  `feedlog program FILE --json` (parse and summarise the whole table in memory)
- sim:      `feedlog sim FILE --stream --blocks-out B.parquet` (windowed, the per-block table)
- sim+1kHz: the same with `--out S.parquet --dt 0.001` (the series at 1 kHz too)
- predict:  `feedlog predict FILE --model mlp.pt --json -o P.parquet` with an MLP trained here for a few
  epochs on synthetic tables (speed, not accuracy; 3-axis programs only, the model is a 3-axis one;
  `predict` holds the whole program, so it is left out above --predict-max blocks)

blocks are the program's motion blocks; bytes/block is the peak RSS over them (the process's baseline, ~150 MB of imports, included).

    .venv/bin/python benchmarks/bench_scale.py [--sizes 10k,100k,1M] [--with-10m] [--kinds 3ax,5ax]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

PASS_POINTS = 400
PROFILES = {"3ax": "linuxcnc-xyz", "5ax": "linuxcnc-xyzac"}


def _surface(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return 4.0 * np.sin(x / 23.0) * np.cos(y / 17.0) + 1.5 * np.sin((x + y) / 7.0)


def write_program(path: Path, n: int, kind: str) -> int:
    """About `n` blocks of mould-like raster finishing, written pass by pass (bounded memory); returns
    the number of motion blocks written."""
    rng = np.random.default_rng(22)
    head = "G21 G90 G17 G64 P0.01 Q0.005\nG0 Z20" + (" A0 C0" if kind == "5ax" else "") + "\n"
    tmp = path.with_suffix(".partial")
    with open(tmp, "w") as f:
        f.write(head)
        blocks, row = 0, 0
        while blocks < n:
            step = rng.uniform(0.15, 0.6, PASS_POINTS)
            x = np.cumsum(step)
            if row % 2:
                x = x[-1] - x
            y = np.full(PASS_POINTS, 0.5 * (row % 400)) + rng.normal(0, 0.002, PASS_POINTS)
            z = _surface(x, y)
            lines = []
            if row % 20 == 0:
                lines += ["G0 Z20", f"G0 X{x[0]:.4f} Y{y[0]:.4f}", f"G1 Z{z[0]:.4f} F800", "F3000"]
            if kind == "5ax":
                a = -20.0 + 15.0 * np.sin(x / 31.0) * np.cos(y / 19.0)
                c = np.degrees(np.arctan2(np.cos(y / 17.0), np.cos(x / 23.0))) + 0.01 * row
                lines += [f"G1 X{p:.4f} Y{q:.4f} Z{s:.4f} A{u:.3f} C{v:.3f}" for p, q, s, u, v in zip(x, y, z, a, c)]
            else:
                lines += [f"G1 X{p:.4f} Y{q:.4f} Z{s:.4f}" for p, q, s in zip(x, y, z)]
            f.write("\n".join(lines) + "\n")
            blocks += len(lines)
            row += 1
        f.write("G0 Z20\nM2\n")
    os.replace(tmp, path)
    return blocks + 2


def run_case(args: list[str]) -> tuple[float, int, str]:
    """Wall time (s), peak RSS (bytes) and stdout of `feedlog ARGS` in a process of its own."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "feedlog", *args], stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)   # this process's rusage alone
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode:
            raise SystemExit(f"feedlog {' '.join(args)} failed: {err.read().strip().splitlines()[-1:]}")
        return wall, usage.ru_maxrss * 1024, out.read()


def _model(path: Path) -> None:
    """A small MLP checkpoint for the predict case, trained once on synthetic tables."""
    if path.exists():
        return
    from feedlog.train import make_model
    from feedlog.train.checkpoint import save_checkpoint
    from feedlog.train.synthetic import synthetic_set

    model = make_model("mlp", preset="quick", epochs=3)
    model.fit(synthetic_set(n_train=4, n_test=0, n_blocks=300, seed=0), progress=False)
    model.fingerprint = "bench_scale"
    save_checkpoint(model, path)


def _size(text: str) -> int:
    text = text.lower()
    scale = {"k": 1_000, "m": 1_000_000}.get(text[-1], 1)
    return int(float(text.rstrip("km")) * scale)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="10k,100k,1M", help="block counts (default 10k,100k,1M)")
    ap.add_argument("--with-10m", action="store_true", help="add 10M blocks")
    ap.add_argument("--kinds", default="3ax,5ax")
    ap.add_argument("--cases", default="program,sim,sim+1kHz,predict")
    ap.add_argument("--predict-max", type=_size, default=1_000_000, help="largest program to predict (default 1M)")
    ap.add_argument("--workdir", type=Path, default=Path(tempfile.gettempdir()) / "feedlog-bench-scale")
    opts = ap.parse_args()
    sizes = [_size(s) for s in opts.sizes.split(",")] + ([10_000_000] if opts.with_10m else [])
    opts.workdir.mkdir(parents=True, exist_ok=True)
    print(f"{'program':>14s} {'case':9s} {'blocks':>9s} {'MB':>7s} {'time s':>8s} {'blocks/s':>10s} "
          f"{'peak RSS MB':>11s} {'B/block':>8s}  result")
    for kind in opts.kinds.split(","):
        for n in sizes:
            path = opts.workdir / f"mould_{kind}_{n}.ngc"
            count = path.with_suffix(".blocks")
            if not (path.exists() and count.exists()):
                t0 = time.perf_counter()
                count.write_text(str(write_program(path, n, kind)))
                print(f"# wrote {path} in {time.perf_counter() - t0:.1f} s", flush=True)
            n_blocks = int(count.read_text())
            profile = PROFILES[kind]
            out_b, out_s = path.with_suffix(".blocks.parquet"), path.with_suffix(".series.parquet")
            out_p = path.with_suffix(".predict.parquet")
            cases = {
                "program": ["program", str(path), "--profile", profile, "--json"],
                "sim": ["sim", str(path), "--profile", profile, "--stream", "-q", "--json", "--force",
                        "--blocks-out", str(out_b)],
                "sim+1kHz": ["sim", str(path), "--profile", profile, "--stream", "-q", "--json", "--force",
                             "--blocks-out", str(out_b), "--out", str(out_s), "--dt", "0.001"],
                "predict": ["predict", str(path), "--model", str(opts.workdir / "mlp.pt"), "--json",
                            "--overwrite", "-o", str(out_p)],
            }
            for case in opts.cases.split(","):
                if case == "predict" and (kind != "3ax" or n > opts.predict_max):
                    continue
                if case == "predict":
                    _model(opts.workdir / "mlp.pt")
                wall, rss, out = run_case(cases[case])
                doc = json.loads(out)
                what = (f"cycle {doc['cycle_time_s']:.1f} s, {doc['blocks']} blocks run (merged chains)"
                        if case.startswith("sim") else f"CAM time {doc['cam_time_s']:.1f} s" if case == "program"
                        else f"predicted cycle {doc['cycle_time_s']:.1f} s")
                if case == "sim+1kHz":
                    what += f", series {out_s.stat().st_size / 1e6:.0f} MB on disk"
                print(f"{path.stem:>14s} {case:9s} {n_blocks:9d} {path.stat().st_size / 1e6:7.1f} {wall:8.2f} "
                      f"{n_blocks / wall:10.0f} {rss / 1e6:11.0f} {rss / n_blocks:8.0f}  {what}", flush=True)
            for p in (out_b, out_s, out_p):
                p.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
