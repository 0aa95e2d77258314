"""Prediction time for a 100k-block program with each block model (target < 1 s on CPU, 2 threads).

Trains each model briefly on synthetic tables (accuracy is not the point here), then times
`model.predict` on a 100 000-block synthetic program, best of 3. Also prints the training time of the
quick preset on the synthetic set. Run: .venv/bin/python benchmarks/bench_train.py [--blocks N]
"""

from __future__ import annotations

import argparse
import time

from feedlog.train import make_model
from feedlog.train.synthetic import synthetic_program, synthetic_set


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=100_000)
    parser.add_argument("--models", default="mlp,bilstm-block,bilstm-r,bilstm-final,hybrid")
    parser.add_argument("--preset", default="quick", help="training preset (full: e.g. bilstm-block's ensemble)")
    parser.add_argument("--epochs", type=int, default=0, help="cap the epochs (0: the preset's)")
    args = parser.parse_args()
    train = [t for t in synthetic_set(n_train=4, n_test=0, n_blocks=300, seed=0)]
    big = synthetic_program(args.blocks, seed=99, feed_mm_min=2000.0, sim_acc_factor=1.5)
    print(f"prediction of a {args.blocks}-block program (best of 3), after a {args.preset}-preset training on "
          f"{sum(len(t.blocks) for t in train)} synthetic blocks")
    for name in args.models.split(","):
        model = make_model(name, preset=args.preset, **({"epochs": args.epochs} if args.epochs else {}))
        start = time.perf_counter()
        model.fit(train, progress=False)
        train_s = time.perf_counter() - start
        model.fingerprint = "benchmark"
        best = float("inf")
        for _ in range(3):
            start = time.perf_counter()
            pred = model.predict(big)
            best = min(best, time.perf_counter() - start)
        print(f"  {name:13s} predict {best:6.3f} s  ({args.blocks / best / 1e3:7.0f} k blocks/s)   "
              f"{args.preset} training {train_s:5.1f} s   cycle time {pred.cycle_time_s:9.1f} s")


if __name__ == "__main__":
    main()
