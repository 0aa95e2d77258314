"""Train every requested model on the training tables and evaluate it on the held-out ones.

`train_and_evaluate` returns (and writes as CSV and Markdown) a table in the papers' shape: one row
per held-out recording with its measured cycle time, CAM's estimate, the simulation's when it ran,
and each model's prediction, with errors in percent as (predicted - measured) / measured.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.atomic import atomic_outputs
from feedlog.errors import ModelError
from feedlog.execution import TaskRunner
from feedlog.storage import writable_dir
from feedlog.train.augment import simulated_tables
from feedlog.train.checkpoint import save_checkpoint
from feedlog.train.dataset import TARGET, ProgramTable, fingerprint
from feedlog.train.model_final import FinalBiLSTM
from feedlog.train.model_hybrid import SIM_COLUMN, attach_sim
from feedlog.train.registry import make_config, model_class, model_names

DEFAULT_MODELS = ("mlp", "bilstm-block", "bilstm-final", "bilstm-r", "hybrid")
RESULTS_CSV, RESULTS_MD, PREDICTIONS_DIR = "results.csv", "results.md", "predictions"


def error_pct(predicted: float, measured: float) -> float:
    return float("nan") if not measured else 100.0 * (predicted - measured) / measured


def _with_sim(tables: Sequence[ProgramTable], log: Callable[[str], None],
              runner: TaskRunner) -> list[ProgramTable | None]:
    """Each table with its simulated block times, or None where the simulation cannot run (said so).

    One task per table on `runner` (the simulations are independent)."""
    out: list[ProgramTable | None] = []
    for t, result in zip(tables, runner.run(attach_sim, tables, desc="simulate", label=lambda t: t.name)):
        if not result.ok:
            log(f"simulation unavailable for {t.name}: {result.error}")
        out.append(result.value if result.ok else None)
    return out


def train_and_evaluate(tables: Sequence[ProgramTable], *, out_dir: str | Path,
                       models: Sequence[str] = DEFAULT_MODELS, seed: int = 0, preset: str = "full",
                       overrides: dict[str, dict[str, Any]] | None = None, overwrite: bool = False,
                       sim_augment: int = 0, progress: bool = True,
                       log: Callable[[str], None] | None = None, runner: TaskRunner | None = None) -> pd.DataFrame:
    """Fit `models` on the 'train' tables, save `<out_dir>/<model>.pt`, evaluate on the 'test' tables.

    `preset` "quick" trains the small, fast variants (the demo's); `overrides` maps a model name to
    config fields. A model that cannot be trained here (the hybrid without a simulator) is skipped
    and said so; the returned frame's `attrs["summary"]` holds per-model training reports.
    `sim_augment` > 0 adds that many simulated training programs per training machine
    (`augment.simulated_tables`) to the data of every model but the hybrid. `runner` (a
    `feedlog.execution.TaskRunner`) runs the hybrid's per-recording simulations in parallel or on a
    cluster (default: here, one by one); training itself runs here.
    """
    log = log or (lambda msg: print(msg, file=sys.stderr))
    for name in models:
        model_class(name)  # unknown names fail before any training
    # a recording a manifest was found for but that it does not list (e.g. recordings/held_back.toml) is not
    # part of the data set: not trained on (--test NAME still holds it out)
    unlisted = [t for t in tables if t.split == "train" and t.metadata.get("unlisted_in")]
    for t in unlisted:
        log(f"{t.name}: not trained on: not listed in {t.metadata['unlisted_in']}")
    # in name order whatever order they came in (a shell glob's locale, the demo's manifest order): the same
    # recordings and seed give the same models from `feedlog train` and `feedlog demo`
    train = sorted((t for t in tables if t.split == "train" and not t.metadata.get("unlisted_in")),
                   key=lambda t: t.name)
    test = [t for t in tables if t.split == "test"]
    if not train:
        raise ModelError("no training recordings (split = 'train')")
    if not test:
        raise ModelError("no held-out test recordings (split = 'test'); name some with --test or the manifest")
    # a held-out recording of a machine no training recording ran on is not a fair test: list it, skip it
    machines = {t.profile.name for t in train if t.profile is not None}
    unseen = [t for t in test if machines and t.profile is not None and t.profile.name not in machines]
    for t in unseen:
        log(f"{t.name}: not evaluated: machine {t.profile.name} has no training recording")
    test = [t for t in test if t not in unseen]
    if not test:
        raise ModelError(f"no held-out recording runs on a trained machine ({', '.join(sorted(machines))})")
    out = Path(out_dir)
    writable_dir(out)  # refused before minutes of training, not after
    there = [p for p in [out / f"{n}.pt" for n in models] + [out / RESULTS_CSV, out / RESULTS_MD] if p.exists()]
    if there and not overwrite:
        raise ModelError(f"{there[0]} exists; refusing to overwrite it (--overwrite replaces it)")
    sim_train: list[ProgramTable | None] = []
    sim_test: list[ProgramTable | None] = [None] * len(test)
    if "hybrid" in models:
        runner = runner or TaskRunner(jobs=1, progress=False)
        sims = _with_sim(train + test, log, runner)
        sim_train, sim_test = sims[:len(train)], sims[len(train):]
    augmented = list(train)
    if sim_augment > 0:
        profiles = {t.profile.name: t.profile for t in train if t.profile is not None}
        if not profiles:
            raise ModelError("--sim-augment needs the training recordings' machine profiles (from the manifest)")
        for i, prof in enumerate(profiles.values()):
            augmented += simulated_tables(prof, n_programs=sim_augment, seed=seed * 100 + i)
        log(f"added {len(augmented) - len(train)} simulated training program(s)")
    rows = [_base_row(t) for t in test]
    if any(t is not None for t in sim_test):
        for row, t in zip(rows, sim_test):
            row["sim_s"] = float("nan") if t is None else float(t.blocks[SIM_COLUMN].sum())
            row["sim_err_pct"] = error_pct(row["sim_s"], row["measured_s"])
    block_preds = {t.name: t.blocks[["block", "line", TARGET]].copy() for t in test}
    summary: dict[str, Any] = {}
    jobs: list[FitJob] = []
    for k, name in enumerate(models, start=1):
        fit_on, test_on = augmented, list(test)
        if name == "hybrid":
            # the hybrid trains on the recordings the simulation could run and predicts only those
            fit_on, test_on = [t for t in sim_train if t is not None], sim_test
            if not fit_on or all(t is None for t in test_on):
                summary[name] = {"skipped": "the simulation could not run on the training or test recordings"}
                log(f"{name}: skipped (no simulation)")
                continue
        config = make_config(name, preset=preset, **{"seed": seed, **(overrides or {}).get(name, {})})
        jobs.append(FitJob(k, name, config, fit_on, test_on, [len(t.blocks) for t in test]))
        log(f"[{k}/{len(models)}] training {name} on {len(fit_on)} program table(s)")
    # each model is seeded and trains on one thread (train.fitting): side by side on the runner's workers
    # they give the weights they give one after the other, in about half the time on two cores
    fitted = _fit_all(jobs, runner, progress=progress)
    for job, (model, train_s) in zip(jobs, fitted):
        k, name, fit_on, test_on = job.k, job.name, job.fit_on, job.test_on
        log(f"[{k}/{len(models)}] {name} trained in {train_s:.1f} s")
        if fit_on[0].profile is not None:
            model.params.setdefault("profile", fit_on[0].profile.name)
            # every machine trained on: `feedlog predict` picks the one whose axes fit a program
            model.params.setdefault("profiles", sorted({t.profile.name for t in fit_on if t.profile is not None}))
        model.fingerprint = fingerprint(fit_on, model.required_columns + [TARGET])
        path = save_checkpoint(model, out / f"{name}.pt", overwrite=overwrite)
        notes: list[str] = []
        for row, t in zip(rows, test_on):
            if t is None:
                row[f"{name}_s"] = row[f"{name}_err_pct"] = float("nan")
                notes.append(f"{row['recording']}: not predicted (no simulation)")
                continue
            pred = model.predict(t)
            row[f"{name}_s"] = pred.cycle_time_s
            row[f"{name}_err_pct"] = error_pct(pred.cycle_time_s, row["measured_s"])
            notes += [f"{t.name}: {n}" for n in pred.notes]
            if pred.durations_s is not None:
                block_preds[t.name][f"{name}_s"] = pred.durations_s
        errs = np.abs([r[f"{name}_err_pct"] for r in rows])
        errs = errs[np.isfinite(errs)]
        summary[name] = {"checkpoint": str(path), "train_s": round(train_s, 2), "fingerprint": model.fingerprint[:16],
                         "mean_abs_err_pct": float(np.mean(errs)), "max_abs_err_pct": float(np.max(errs)),
                         "report": model.report, "notes": notes}
        log(f"{name}: trained in {train_s:.1f} s, mean |error| {np.mean(errs):.2f} % on {len(errs)} test recording(s)")
    results = pd.DataFrame(rows)
    results.attrs["summary"] = summary
    results.attrs["not_evaluated"] = {t.name: f"machine {t.profile.name} has no training recording" for t in unseen}
    _write(results, block_preds, out, overwrite=overwrite)
    return results


@dataclass
class FitJob:
    """One model to train: its place in the list, name, config, training tables and test tables."""

    k: int
    name: str
    config: Any
    fit_on: list[ProgramTable]
    test_on: list[ProgramTable | None]
    target_lengths: list[int]


def _fit(job: FitJob, progress: bool = False) -> tuple[Any, float]:
    """Train one model (on a worker or here); the fitted model and its training time in seconds."""
    cls = model_class(job.name)
    model = cls(job.config, target_lengths=job.target_lengths) if cls is FinalBiLSTM else cls(job.config)
    start = time.perf_counter()
    model.fit(job.fit_on, progress=progress)
    return model, time.perf_counter() - start


def _fit_all(jobs: list[FitJob], runner: TaskRunner | None, *, progress: bool) -> list[tuple[Any, float]]:
    """Every job's fitted model, in order: on the runner's workers when it has more than one (the
    tables go to them once per model), else here one after the other with a progress bar."""
    if runner is None or runner.name == "serial" or len(jobs) < 2:
        return [_fit(job, progress) for job in jobs]
    out = []
    for job, result in zip(jobs, runner.run(_fit, [_trimmed(job) for job in jobs], desc="train",
                                            label=lambda job: job.name)):
        if not result.ok:
            raise ModelError(f"{job.name}: training failed: {result.error}")
        out.append(result.value)
    return out


def _trimmed(job: FitJob) -> FitJob:
    """What a worker needs of a job: the tables it trains on, not the ones it is tested on."""
    return FitJob(job.k, job.name, job.config, job.fit_on, [], job.target_lengths)


def _base_row(t: ProgramTable) -> dict[str, Any]:
    feed = t.blocks["feed_mm_min"].dropna()
    tol = t.blocks["tol_mm"]
    measured = t.measured_cycle_time_s
    return {"recording": t.name, "program": t.program, "blocks": len(t.blocks),
            "feed_mm_min": float(feed.median()) if len(feed) else float("nan"),
            "tol_mm": float(tol.median()) if tol.notna().any() else float("nan"),
            "measured_s": measured, "cam_s": t.cam_time_s, "cam_err_pct": error_pct(t.cam_time_s, measured)}


def _write(results: pd.DataFrame, block_preds: dict[str, pd.DataFrame], out: Path, *, overwrite: bool) -> None:
    for name in (RESULTS_CSV, RESULTS_MD):
        if (out / name).exists() and not overwrite:
            raise ModelError(f"{out / name} exists; refusing to overwrite it")
    pred_dir = out / PREDICTIONS_DIR
    writable_dir(pred_dir)
    names = list(block_preds)
    with atomic_outputs(out / RESULTS_CSV, out / RESULTS_MD, *(pred_dir / f"{n}.parquet" for n in names)) as paths:
        results.to_csv(paths[0], index=False)
        paths[1].write_text(format_results(results, markdown=True) + "\n")
        for name, path in zip(names, paths[2:]):
            block_preds[name].to_parquet(path, index=False)


def model_columns(results: pd.DataFrame) -> list[str]:
    known = set(model_names()) | {"cam", "sim"}
    return [c[:-2] for c in results.columns if c.endswith("_s") and c[:-2] in known and c != "measured_s"]


def format_results(results: pd.DataFrame, *, markdown: bool = False) -> str:
    """The papers' table: measured time, then each estimate as `seconds (err %)`; a mean |error| row."""
    names = model_columns(results)
    header = ["recording", "F mm/min", "tol mm", "blocks", "measured s"] + [f"{n} s (err)" for n in names]
    body = []
    for _, r in results.iterrows():
        cells = [str(r["recording"]), f"{r['feed_mm_min']:.0f}", f"{r['tol_mm']:g}", str(int(r["blocks"])),
                 f"{r['measured_s']:.3f}"]
        cells += [f"{r[f'{n}_s']:.3f} ({r[f'{n}_err_pct']:+.2f} %)" if np.isfinite(r[f"{n}_s"]) else "n/a"
                  for n in names]
        body.append(cells)
    body.append(["mean |error|", "", "", "", ""] + [f"{np.nanmean(np.abs(results[f'{n}_err_pct'])):.2f} %" for n in names])
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        return "\n".join(lines + ["| " + " | ".join(c) + " |" for c in body])
    widths = [max(len(row[i]) for row in [header] + body) for i in range(len(header))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(row, widths)) for row in [header] + body)
