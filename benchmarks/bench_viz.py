"""Export throughput of the Rerun overlays: measured samples per second from recording to .rrd.

Builds a synthetic 1 kHz five-axis recording (a dense polyline with a feed profile), a simulation
series of the same length and a model series, then times `prepare_view` and `save_view` separately.
`samples/s` counts measured samples (one per axis stream row) exported; the total number of scalars
and points sent to Rerun is printed too. Run: .venv/bin/python benchmarks/bench_viz.py [--samples N]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.ingest.recording import Recording
from feedlog.rerun_stream import new_stream
from feedlog.viz.overlay import log_view, save_view
from feedlog.viz.prepare import ModelPrediction, ViewInputs, prepare_view


def synthetic_inputs(n: int, *, seed: int = 0) -> ViewInputs:
    rng = np.random.default_rng(seed)
    t_ns = np.arange(n, dtype=np.int64) * 1_000_000
    s = np.linspace(0.0, n * 0.02, n)
    xyz = np.column_stack([30 * np.cos(s / 30), 30 * np.sin(s / 30), 0.001 * s])
    feed = 1200.0 + 100.0 * np.sin(s) + rng.normal(0, 5, n)
    blocks = (s // 2.0).astype(np.int64)
    line = blocks + 1
    change = np.concatenate([[0], np.flatnonzero(np.diff(line)) + 1])
    axes = pd.DataFrame({"t_ns": t_ns, "x_mm": xyz[:, 0], "y_mm": xyz[:, 1], "z_mm": xyz[:, 2],
                         "a_deg": 20 * np.sin(s / 50), "c_deg": np.degrees(s / 30)})
    rec = Recording(streams={"axes": axes, "feed": pd.DataFrame({"t_ns": t_ns, "feed_mm_min": feed}),
                             "line": pd.DataFrame({"t_ns": t_ns[change], "line": line[change]})})
    nb = int(blocks.max()) + 1
    program_blocks = pd.DataFrame({"block": np.arange(nb), "line": np.arange(nb) + 1,
                                   "kind": pd.Categorical(["linear"] * nb), "feed_mm_min": np.full(nb, 1200.0)})
    sim = axes[["t_ns", "x_mm", "y_mm", "z_mm"]].assign(feed_mm_min=feed * 0.98, block=blocks)
    g = sim.groupby("block")["t_ns"]
    sim_blocks = pd.DataFrame({"block": g.min().index, "t_start_ns": g.min().to_numpy(), "t_end_ns": g.max().to_numpy()})
    sim_blocks["duration_s"] = (sim_blocks["t_end_ns"] - sim_blocks["t_start_ns"]) / 1e9
    model = ModelPrediction("mlp", blocks=sim_blocks[["block", "duration_s"]],
                            series=pd.DataFrame({"t_ns": t_ns, "feed_mm_min": feed * 1.01}))
    return ViewInputs(rec, name="bench", program_blocks=program_blocks, program_path=axes[["x_mm", "y_mm", "z_mm"]],
                      sim_series=sim, sim_blocks=sim_blocks, models=[model], arrow_every=200)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    inputs = synthetic_inputs(args.samples)
    best_prep = best_save = best_mem = float("inf")
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            data = prepare_view(inputs)
            t1 = time.perf_counter()
            counts = save_view(data, Path(tmp) / "bench.rrd")
            t2 = time.perf_counter()
            stream = new_stream("bench-memory")
            memory = stream.memory_recording()
            t3 = time.perf_counter()
            log_view(data, stream)
            stream.flush()
            t4 = time.perf_counter()
            memory.drain_as_bytes()
            stream.disconnect()
            best_prep, best_save, best_mem = min(best_prep, t1 - t0), min(best_save, t2 - t1), min(best_mem, t4 - t3)
        size_mb = (Path(tmp) / "bench.rrd").stat().st_size / 1e6
    sent = sum(counts.values())
    print(f"measured samples: {args.samples:,} (five-axis, with sim, one model); series: {len(counts)}; "
          f"values sent over time: {sent:,}; .rrd {size_mb:.1f} MB")
    print(f"prepare_view: {best_prep:.2f} s  ({args.samples / best_prep / 1e6:.2f} M samples/s)")
    print(f"save_view (Rerun export): {best_save:.2f} s  ({args.samples / best_save / 1e6:.2f} M samples/s, "
          f"{sent / best_save / 1e6:.1f} M values/s)")
    print(f"log_view to a memory sink (SDK cost without file encoding): {best_mem:.2f} s  "
          f"({args.samples / best_mem / 1e6:.2f} M samples/s, {sent / best_mem / 1e6:.1f} M values/s)")
    total = best_prep + best_save
    print(f"end to end to .rrd: {total:.2f} s  ({args.samples / total / 1e6:.2f} M samples/s)")


if __name__ == "__main__":
    main()
