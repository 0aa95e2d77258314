"""`feedlog train ALIGNED... [--models ...] -o OUTDIR`: train models, print the papers' cycle-time table.

ALIGNED are `feedlog align` output folders (one per recording, or their parent). The recordings
manifest says which are held out for testing (`--test` overrides). Writes OUTDIR/<model>.pt,
OUTDIR/results.csv, OUTDIR/results.md and per-block predictions in OUTDIR/predictions/.
"""

from __future__ import annotations

import argparse
import json
import sys

from feedlog.errors import ModelError
from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.execution import add_arguments as add_execution_arguments
from feedlog.execution import task_runner
from feedlog.train.evaluate import DEFAULT_MODELS, format_results, train_and_evaluate
from feedlog.train.load import load_many
from feedlog.train.registry import PRESETS, model_names


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("aligned", nargs="+", metavar="ALIGNED_DIR", help="feedlog align output folder(s)")
    add_output(parser, required=True, metavar="OUTDIR", aliases=("--outdir",), help="folder for checkpoints and results")
    parser.add_argument("--models", default=",".join(DEFAULT_MODELS),
                        help="comma-separated model names (default: %(default)s)")
    parser.add_argument("--preset", choices=PRESETS, default="full",
                        help="'quick' trains small, fast variants (the demo's)")
    parser.add_argument("--manifest", help="recordings manifest.toml (default: found next to the recordings)")
    parser.add_argument("--test", action="append", default=[], metavar="NAME",
                        help="hold out this recording for testing (repeatable; overrides the manifest)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--epochs", type=int, help="override every model's maximum number of epochs")
    parser.add_argument("--sim-augment", type=int, default=0, metavar="N",
                        help="add N simulated training programs per machine (feedlog.sim; not for the hybrid)")
    add_overwrite(parser, help="replace existing checkpoints and results")
    add_quiet(parser, help="no progress bars")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    add_execution_arguments(parser, jobs_help="local worker processes for reading the aligned folders, the "
                                              "hybrid's simulations and training the models side by side "
                                              "(default: all cores)")


def _train(args: argparse.Namespace, models: list[str], tables, runner):
    n_train = sum(t.split == "train" for t in tables)
    print(f"{len(tables)} aligned recording(s): {n_train} for training, {len(tables) - n_train} held out",
          file=sys.stderr if args.json else sys.stdout)  # --json: stdout is one JSON document
    overrides = {m: {"epochs": args.epochs} for m in models} if args.epochs else None
    return train_and_evaluate(tables, out_dir=args.out, models=models, seed=args.seed, preset=args.preset,
                              overrides=overrides, overwrite=args.overwrite, sim_augment=args.sim_augment,
                              progress=not args.quiet, runner=runner)


def run(args: argparse.Namespace) -> int:
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    known = model_names()
    bad = [m for m in models if m not in known]
    if bad or not models:
        raise ModelError(f"unknown model(s) {', '.join(bad) or '(none given)'}; known: {', '.join(known)}")
    with task_runner(jobs=args.jobs, scheduler=args.scheduler, progress=not args.quiet) as runner:
        tables = load_many(args.aligned, manifest=args.manifest, test=args.test, runner=runner)
        results = _train(args, models, tables, runner)
    if args.json:
        doc = {"results": results.to_dict(orient="records"), "summary": results.attrs.get("summary", {})}
        print(json.dumps(doc, indent=1, default=str))
        return 0
    print(format_results(results))
    print()
    for name, info in results.attrs.get("summary", {}).items():
        if "skipped" in info:
            print(f"{name}: skipped: {info['skipped']}")
            continue
        print(f"{name}: trained in {info['train_s']:.1f} s, mean |error| {info['mean_abs_err_pct']:.2f} %, "
              f"max {info['max_abs_err_pct']:.2f} % -> {info['checkpoint']}")
        for note in info.get("notes", []):
            print(f"  note: {note}")
    for name, why in results.attrs.get("not_evaluated", {}).items():
        print(f"{name}: not evaluated: {why}")
    print(f"results: {args.out}/results.csv, results.md; per-block predictions in {args.out}/predictions/")
    return 0
