"""`feedlog demo [--out DIR] [--json]`: the main job, end to end on the bundled recordings.

Verifies the recordings, aligns them, simulates, trains and predicts with every stage this
installation has, then writes into DIR: `report.md` (the cycle-time table and PNG plots),
`cycle_times.json`, `rerun/demo.rrd` (every recording, each its own Rerun recording, one layout),
the trained models under `models/`.
It prints where everything is and how to open it. `--json` prints only the table (JSON rows).
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import shutil
import sys
import time
from pathlib import Path

import rerun as rr

from feedlog.errors import FeedlogError
from feedlog.cli_options import add_output
from feedlog.execution import add_arguments as add_execution_arguments
from feedlog.viz.decimate import SCREEN_COLUMNS
from feedlog.viz.bundle import rrd_bundle
from feedlog.viz.mystery import Mystery, diagnose_mystery
from feedlog.viz.pipeline import DemoConfig, DemoResult, RecordingRun, discover, run_demo, trim_heap, view_of
from feedlog.viz.plot_worker import PlotWorker
from feedlog.viz.plots import plot_cycle_times
from feedlog.viz.answer import TERMS, summary_sentences
from feedlog.viz.report import ReportSection, TableRow, cycle_time_table, headline, table_json, write_report

DEFAULT_RECORDINGS = Path("recordings")
DEFAULT_OUT = Path("demo-out")
MARKER = ".feedlog-demo"   # marks a folder the demo wrote, so a rerun may replace it
DETAIL_PLOTS = 4  # recordings that get all four plots; the others get the feed plot
TRIM_EVERY = 4    # recordings written between two trims of the heap (each costs time: pages are faulted in again)
RRD_NAME = "demo.rrd"       # under rerun/: every recording's overlays in one file (`viz.bundle`)
OUTPUTS = ("report.md", "cycle_times.json", "plots", "rerun", "models", "diagnose", MARKER)


def configure(parser: argparse.ArgumentParser) -> None:
    add_output(parser, type=Path, default=DEFAULT_OUT, metavar="OUTDIR",
               help=f"output folder (default: {DEFAULT_OUT}); an earlier demo's outputs there are replaced")
    parser.add_argument("--recordings", type=Path, default=None,
                        help="recordings folder (default: the bundled recordings/)")
    parser.add_argument("--json", action="store_true", help="print the cycle-time table as JSON rows only")
    parser.add_argument("--no-train", action="store_true", help="skip training and prediction")
    parser.add_argument("--no-rrd", action="store_true",
                        help="write no Rerun .rrd (rerun/demo.rrd: about 0.27 MB per recording; plots and report only)")
    parser.add_argument("--models", help="comma-separated model names to train (default: the demo set)")
    parser.add_argument("--detail-plots", type=int, default=DETAIL_PLOTS, metavar="N",
                        help=f"recordings that get all four plots, the rest get the feed plot (default {DETAIL_PLOTS})")
    add_execution_arguments(parser, jobs_help="local worker processes for verify, align and simulate "
                                              "(default: all cores); training and plots run here")


def default_recordings() -> Path:
    """`recordings/` of the working directory, else the one next to the installed sources."""
    here = DEFAULT_RECORDINGS
    if here.is_dir():
        return here
    repo = Path(__file__).resolve().parents[1] / "recordings"
    return repo if repo.is_dir() else here


def prepare_out(out: Path) -> None:
    """Create `out`, or clear what an earlier demo wrote there; never touch a folder the demo did not make."""
    if out.exists():
        if not out.is_dir():
            raise FeedlogError(f"{out} exists and is not a folder")
        if any(out.iterdir()) and not (out / MARKER).exists():
            raise FeedlogError(f"{out} exists, is not empty and was not written by feedlog demo; "
                               "choose another --out")
        for name in OUTPUTS:
            target = out / name
            if target.is_dir():
                shutil.rmtree(target)
            elif target.exists():
                target.unlink()
    out.mkdir(parents=True, exist_ok=True)
    (out / MARKER).write_text("written by feedlog demo; rerunning the demo replaces this folder's outputs\n")


def _rows(result: DemoResult) -> list[TableRow]:
    rows = []
    for run in result.runs:
        models = {name: p.cycle_time_s for name, p in run.models.items()}
        rows.append(TableRow(program=run.entry.program, recording=run.entry.name, split=run.entry.split,
                             measured_s=run.measured_s, cam_s=run.cam_s, sim_s=run.sim_s, models=models))
    return rows


def detail_runs(result: DemoResult, count: int) -> set[str]:
    """Recordings that get every plot, `count` in all: held-out (test) ones first, one per program
    family and five-axis ones early, so the report shows the variety of the set."""
    shown = [r for r in result.runs if r.data is not None or r.has_view]
    chosen: list[RecordingRun] = []
    families: set[str] = set()
    for run in sorted(shown, key=lambda r: (r.entry.split != "test", len(r.data.axes if r.data else r.view_axes) <= 3)):
        if len(chosen) < count and (not run.entry.family or run.entry.family not in families):
            chosen.append(run)
            families.add(run.entry.family)
    for run in shown:  # fewer families than `count`: fill up in order
        if len(chosen) < count and run not in chosen:
            chosen.append(run)
    return {r.entry.name for r in chosen}


def write_outputs(result: DemoResult, out: Path, *, log, detail: int = DETAIL_PLOTS,
                  mystery: Mystery | None = None, rrd: bool = True, started: float | None = None,
                  release: bool = True, plot_workers: int = 1) -> dict[str, Path]:
    """Plots, the .rrd, JSON table and the Markdown report; returns what was written (and `answer`,
    the sentences the report starts with).

    Every recording gets its feed plot and its own recording in `rerun/demo.rrd` (downsampled to the
    blueprint's views, `viz.decimate`; one blueprint for all); `detail` recordings also get the axis, path and
    block-time plots (matplotlib is the slow part of the demo). `started` (`time.perf_counter()` when
    the demo began): the run time the report and the console both quote, taken before the report is written.
    `release`: drop each recording's samples (`run.data`, `run.gathered`, `run.recording`) once its plots
    and .rrd are written. `plot_workers`: processes drawing the PNG plots beside the .rrd logging
    (`viz.plot_worker`; 0 draws them here).
    """
    demo_started, plots_started = started, time.perf_counter()
    plots_dir, rerun_dir = out / "plots", out / "rerun"
    model_names = list(result.training.checkpoints) if result.training and result.training.available else []
    table = cycle_time_table(_rows(result), model_names=model_names)
    detailed = detail_runs(result, detail)
    rrd_path = rerun_dir / RRD_NAME
    rrd = rrd and any(run.data is not None or run.has_view for run in result.runs)
    if rrd:
        rerun_dir.mkdir(parents=True, exist_ok=True)
    with ((rrd_bundle(rrd_path) if rrd else contextlib.nullcontext()) as bundle,
          PlotWorker(plot_workers) as plotter):
        for k, run in enumerate(result.runs, start=1):
            run.data = view_of(run)  # built again here when the pipeline did not hold every recording's (peak memory)
            if run.data is None:
                continue
            kinds = None if run.entry.name in detailed else ("feed",)
            plotter.submit(run.entry.name, run.data, plots_dir, stem=run.entry.name, kinds=kinds)  # drawn beside
            if bundle is not None:
                bundle.add(run.data, columns=SCREEN_COLUMNS)
                run.rrd = rrd_path
            log(f"[{k}/{len(result.runs)}] {run.entry.name}: " + ("Rerun recording written, " if rrd else "")
                + "plots drawing")
            run.view_notes = list(run.data.notes)
            if release:  # written: the recording's samples are not needed again (peak memory, benchmarks/bench_demo.py)
                run.data = run.gathered = run.recording = None
                gc.collect(1)  # matplotlib's figures are young reference cycles: free them now (a full collection takes ~0.5 s)
                _drop_finished_streams()
                if k % TRIM_EVERY == 0:  # and give the pages back: freed tables leave holes that grow the peak
                    trim_heap()
        drawn = plotter.results()
    for run in result.runs:
        run.plots = drawn.get(run.entry.name, run.plots)
    bars = plot_cycle_times(table, plots_dir / "cycle_times.png") if len(table) else None
    result.timings_s["plots_and_rrd"] = time.perf_counter() - plots_started
    if demo_started is not None:
        result.timings_s["total"] = time.perf_counter() - demo_started
    else:
        result.timings_s["total"] = result.timings_s.get("total", 0.0) + result.timings_s["plots_and_rrd"]
    json_path = out / "cycle_times.json"
    json_path.write_text(table_json(table) + "\n")
    front = [_mystery_section(mystery, out)] if mystery is not None else []
    if bars is not None:
        front.append(ReportSection("Cycle time per program", images=[("cycle times", bars)],
                                   lines=[_BARS_CAPTION]))
    answer = [*_mystery_answer(mystery),
              *summary_sentences(table, run_time_s=result.timings_s["total"], models=model_names)]
    report = write_report(out / "report.md", title="feedlog demo: cycle times on the bundled recordings",
                          answer=[*answer, "", *TERMS], front=front, intro=_intro(result, out), table=table,
                          sections=_sections(result))
    return {"report": report, "json": json_path, "rerun": rerun_dir, "plots": plots_dir,
            "models": out / "models", "table": table, "answer": answer}


def _drop_finished_streams() -> None:
    """Rerun holds a dropped recording stream until its next `rr.init` cleans up the orphans: do it per
    recording (about 0.5 MB each, measured with 30 saved views)."""
    cleanup = getattr(getattr(rr, "bindings", None), "flush_and_cleanup_orphaned_recordings", None)
    if cleanup is not None:
        cleanup()


_BARS_CAPTION = ("Left: each estimate against the measured cycle time; right: its error in percent (a "
                 "symmetric-log axis: linear within +-1 %, logarithmic beyond, so the simulation's 0.1 % and "
                 "the CAM time's 60 % both show). The hybrid is drawn as rings: it is the simulation times a "
                 "learned correction, and where it learned none its rings sit around the simulation's points.")


def _mystery_answer(mystery: Mystery | None) -> list[str]:
    if mystery is None:
        return []
    if mystery.error:
        return [f"The mystery machine (recordings/mystery/) could not be diagnosed: {mystery.error}"]
    return ["The mystery machine (recordings/mystery/: a LinuxCNC machine that differs from its profile in one "
            "undisclosed way), diagnosed by `feedlog diagnose`:", "", *mystery.answer, ""]


def _intro(result: DemoResult, out: Path) -> list[str]:
    lines = ["## How the demo ran", "",
             f"Recordings: {len(result.runs)}. Run time {result.timings_s.get('total', 0):.1f} s, of which "
             f"{', '.join(f'{k} {v:.1f} s' for k, v in result.timings_s.items() if k != 'total')}.", "",
             "Columns: measured cycle time (first block start to last block end), CAM (every block at its "
             "programmed feed), simulation (feedlog.sim on the recording's machine profile), and each trained "
             "model; errors are (predicted - measured) / measured. `n/a`: not available (see below).", "",
             "### Pipeline stages", ""]
    for stage, reason in result.stages.items():
        lines.append(f"- {stage}: " + ("available" if reason is None else f"**not available** — {reason}"))
    if result.training is not None:
        if result.training.available:
            paths = ", ".join(f"`{_rel(p, out)}`" for p in result.training.checkpoints.values()) or "none"
            lines.append(f"- trained models: {paths} (train/'s own held-out evaluation: "
                         f"`{_rel(out / 'models' / 'results.md', out)}`); model columns of `train` rows are "
                         "in-sample, of `test` rows held out")
            lines += [f"  - {note}" for note in result.training.notes]
        else:
            lines.append(f"- training skipped: {result.training.reason}")
    else:
        lines.append("- training skipped (--no-train)")
    from_lines = [r.entry.name for r in result.runs if r.measured_source == "line stream"]
    if from_lines:
        lines.append(f"- measured cycle time taken from the program-line stream (not aligned, see the recording's "
                     f"section) for {len(from_lines)} recording(s): {', '.join(from_lines)}")
    return lines


def _mystery_section(mystery: Mystery, out: Path) -> ReportSection:
    s = ReportSection("The mystery machine: what feedlog diagnose finds")
    if mystery.error:
        s.lines.append(f"- error: {mystery.error}")
        return s
    s.lines.append("recordings/mystery/ holds three sessions of a LinuxCNC machine that differs from its profile "
                   "(linuxcnc-xyz) in one way nobody wrote down. `feedlog diagnose recordings/mystery/*.mcap` "
                   f"({mystery.seconds:.1f} s):")
    s.lines += ["", "```", *mystery.lines, "```", "",
                f"Full diagnosis: `{_rel(mystery.report, out)}` (tables, plots, `diagnose.rrd`, the extended "
                "`profile.toml`)."]
    s.images = [(name, path) for name, path in mystery.images if name.startswith("profile_")][:1]
    return s


def _rel(path: Path, root: Path) -> str:
    path = Path(path)
    return path.relative_to(root).as_posix() if path.is_relative_to(root) else str(path)


def _sections(result: DemoResult) -> list[ReportSection]:
    sections = []
    for run in result.runs:
        s = ReportSection(f"{run.entry.name} ({run.entry.split})")
        s.lines.append(f"File `{run.entry.path}`; program `{run.entry.program}`.")
        if run.summary:
            streams = ", ".join(f"{k} {v}" for k, v in run.summary["streams"].items())
            s.lines.append(f"Duration {run.summary['duration_s']} s; samples per stream: {streams}; "
                           f"dropped frames {run.summary['dropped_frames']}"
                           + ("; samples and dropped frames match the manifest." if run.summary.get("manifest")
                              else "."))
        if run.measured_source:
            s.lines.append(f"Measured cycle time from {run.measured_source}.")
        if run.rrd is not None:
            s.lines.append(f"Rerun: `rerun {run.rrd}`, recording `{run.entry.name}` (full rate: "
                           f"`feedlog view {run.entry.path} --sim`)")
        s.lines += [f"- error: {e}" for e in run.errors] + [f"- note: {n}" for n in run.notes]
        s.lines += [f"- note: {n}" for n in run.view_notes]
        s.images = [(f"{run.entry.name} {kind}", path) for kind, path in run.plots.items()]
        sections.append(s)
    return sections


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    log = (lambda msg: print(msg, file=sys.stderr)) if args.json else print
    recordings = args.recordings or default_recordings()
    models = tuple(m.strip() for m in args.models.split(",") if m.strip()) if args.models else None
    config = DemoConfig(recordings=recordings, out=args.out, train=not args.no_train, models=models, log=log,
                        jobs=args.jobs, scheduler=args.scheduler, progress=not args.json, keep_views=False)
    discover(config.recordings)  # a broken manifest is refused before the output folder is touched
    prepare_out(args.out)
    result = run_demo(config)
    mystery = diagnose_mystery(recordings, args.out, log=log)
    if mystery is not None:
        result.timings_s["diagnose"] = mystery.seconds
        trim_heap()  # what the diagnosis freed, before the plots and the .rrd (peak memory)
    written = write_outputs(result, args.out, log=log, detail=args.detail_plots, mystery=mystery, rrd=not args.no_rrd,
                            started=started)
    if args.json:
        print(table_json(written["table"]))
        return 0
    rrds = [r for r in result.runs if r.rrd is not None]
    print()
    print(f"feedlog demo finished in {result.timings_s['total']:.1f} s")
    print("\n".join(written["answer"]).strip("\n"))
    print()
    print("\n".join(headline(written["table"])))
    print()
    print(f"  report (Markdown + PNG plots): {written['report']}")
    print(f"  cycle-time table (JSON):       {written['json']}")
    if result.training is not None and result.training.available:
        print(f"  trained models:                {written['models']}/<name>.pt  (feedlog predict PROGRAM --model ...)")
    if rrds:
        print(f"  Rerun (every recording, one layout): rerun {rrds[0].rrd}   (pick a recording in the "
              "recordings panel)")
        print(f"  one recording at full rate:    feedlog view {rrds[0].entry.path} --sim")
    if mystery is not None and mystery.report is not None:
        print(f"  the mystery machine diagnosed: {mystery.report.parent}/ (report.md, profile.toml, diagnose.rrd)")
    missing = [s for s, reason in result.stages.items() if reason]
    if missing:
        print(f"  stages not available here: {', '.join(missing)} (the report says why)")
    if mystery is not None:
        print()
        print("The mystery machine (recordings/mystery/, one undisclosed change), feedlog diagnose:")
        print("\n".join(f"  {line}" for line in mystery.lines) if mystery.lines else f"  error: {mystery.error}")
    print()
    print(f"The cycle time of every recording: {written['report']} (section \"Cycle times\") and {written['json']}.")
    return 0
