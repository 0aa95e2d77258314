"""The main job: recordings -> verify -> align -> simulate -> train -> predict -> overlays and report.

`run_demo(DemoConfig(...))` runs every stage that is available in this installation on every
recording and collects one `RecordingRun` per recording. A stage that is missing, or that fails on
one recording, leaves its numbers empty and says why (`notes`, `errors`); the other stages and
recordings go on. Nothing is estimated in place of a missing stage.
"""

from __future__ import annotations

import ctypes
import time
from collections.abc import Callable
from dataclasses import dataclass, field, is_dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from feedlog import storage
from feedlog.errors import FeedlogError
from feedlog.manifest import MANIFEST, read_manifest
from feedlog.execution import TaskRunner, task_runner
from feedlog.recording import PROGRAM_ATTACHMENT, Recording
from feedlog.viz.prepare import ModelPrediction, ViewData, prepare_view
from feedlog.viz.sources import Gathered, finite_or_none, gather
from feedlog.viz.stages import StageMissing, availability, stage_function
from feedlog.viz.training import TrainOutcome, predict_for, train_models



@dataclass
class DemoConfig:
    recordings: Path
    out: Path
    train: bool = True
    models: tuple[str, ...] | None = None   # None: the demo set of viz.training
    preset: str = "quick"
    log: Callable[[str], None] = print
    jobs: int | None = None               # feedlog.execution: local processes (None: all cores) ...
    scheduler: str | None = None          # ... or a Dask cluster for the per-recording stages
    progress: bool = False
    keep_views: bool = True               # False: each recording's ViewData is built again when written
                                          # (`view_of`), not held for all recordings at once (peak memory)

    def __post_init__(self) -> None:
        self.recordings, self.out = Path(self.recordings), Path(self.out)
        if not self.recordings.is_dir():
            raise FeedlogError(f"{self.recordings}: recordings folder not found")


@dataclass
class RecordingEntry:
    path: Path
    name: str
    program: str
    split: str = "train"
    family: str = ""                      # manifest's program family (corners, pocket, ...)
    program_path: Path | None = None      # manifest's program file (used when none is attached)
    profile: str | None = None            # manifest's machine profile (before an attached one: its [sim]
                                          # tables are today's model, an attachment's those of the recording day)
    expected: dict[str, Any] = field(default_factory=dict)   # manifest's samples, dropped_frames, cycle_time_s


@dataclass
class RecordingRun:
    entry: RecordingEntry
    recording: Recording | None = None
    gathered: Gathered | None = None
    data: ViewData | None = None
    measured_s: float | None = None
    measured_source: str = ""
    cam_s: float | None = None
    sim_s: float | None = None
    models: dict[str, ModelPrediction] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    plots: dict[str, Path] = field(default_factory=dict)
    rrd: Path | None = None
    view_notes: list[str] = field(default_factory=list)   # the overlays' notes, kept when `data` is released
    view_axes: tuple[str, ...] = ()       # the overlays' axes, known when `data` is not held
    has_view: bool = False                # the overlays were built (`data`, or `view_of` builds them again)


@dataclass
class DemoResult:
    runs: list[RecordingRun]
    stages: dict[str, str | None]
    training: TrainOutcome | None
    timings_s: dict[str, float] = field(default_factory=dict)


def discover(folder: Path) -> list[RecordingEntry]:
    """Recordings listed in `manifest.toml` (when present, `feedlog.manifest`), else every `*.mcap` in the folder."""
    manifest = folder / MANIFEST
    if not manifest.is_file():
        return [RecordingEntry(path=p, name=p.stem, program=p.stem) for p in sorted(folder.glob("*.mcap"))]
    return [RecordingEntry(path=e.path, name=e.name, program=Path(e.program).stem if e.program else e.name,
                           split=e.split, family=e.family, program_path=e.program_path, profile=e.profile,
                           expected=e.expected)
            for e in read_manifest(manifest)]


def verify(run: RecordingRun) -> bool:
    """Read the recording and check what the pipeline needs; problems go to `run.errors`/`run.notes`."""
    try:
        recording = stage_function("read_recording")(run.entry.path)
    except FeedlogError as exc:
        run.errors.append(f"cannot read: {exc}")
        return False
    run.recording = recording
    run.summary = {
        "duration_s": round(recording.duration_s, 3),
        "streams": {name: len(table) for name, table in recording.streams.items()},
        "dropped_frames": recording.dropped_frames,
        "program_attached": PROGRAM_ATTACHMENT in recording.attachments,
    }
    if "axes" not in recording.streams:
        run.errors.append("no 'axes' stream: nothing to show or align")
        return False
    if recording.dropped_frames:
        run.notes.append(f"{recording.dropped_frames} frames were dropped while recording")
    if PROGRAM_ATTACHMENT not in recording.attachments and run.entry.program_path is None:
        run.notes.append("no part program attached or listed: no alignment, simulation or prediction")
    _check_manifest(run)
    return True


def _check_manifest(run: RecordingRun) -> None:
    """Compare the file with what the manifest says was recorded."""
    expected, rec = run.entry.expected, run.recording
    samples = len(rec.streams["axes"])
    if "samples" in expected and int(expected["samples"]) != samples:
        run.errors.append(f"manifest lists {expected['samples']} samples, the file's axes stream has {samples}")
    if "dropped_frames" in expected and int(expected["dropped_frames"]) != rec.dropped_frames:
        run.errors.append(f"manifest lists {expected['dropped_frames']} dropped frames, the file says "
                          f"{rec.dropped_frames}")
    if expected and not run.errors:
        run.summary["manifest"] = "matches"


def _check_cycle_time(run: RecordingRun) -> None:
    expected = run.entry.expected.get("cycle_time_s")
    if expected is None or run.measured_s is None:
        return
    if abs(float(expected) - run.measured_s) > 0.005:
        run.notes.append(f"measured cycle time {run.measured_s:.3f} s ({run.measured_source}) differs from the "
                         f"manifest's {float(expected):.3f} s")


def _measured(run: RecordingRun) -> None:
    aligned = run.gathered.aligned if run.gathered else None
    value = getattr(aligned, "cycle_time_s", None)
    if value is not None:
        run.measured_s, run.measured_source = finite_or_none(value), "align"
        return
    if run.data is not None and run.data.blocks["measured_s"].notna().any():
        # not aligned: the span of the motion blocks seen in the recording's line stream
        block = run.data.measured["block"]
        program = run.gathered.program if run.gathered else None
        inside = block.isin(program.motion["block"]) if program is not None else block >= 0
        if inside.any():
            t = run.data.measured.loc[inside, "t_ns"]
            run.measured_s = (int(t.iloc[-1]) - int(t.iloc[0])) / 1e9
            run.measured_source = "line stream"


def _cam(run: RecordingRun) -> None:
    g = run.gathered
    if g is None:
        return
    if g.sim is not None:
        run.cam_s = finite_or_none(g.sim.cam_time_s)
        run.sim_s = finite_or_none(g.sim.cycle_time_s)
        return
    if g.program is None:
        return
    def cam_from_features() -> float:
        features = stage_function("block_features")(g.program, g.profile)
        dwell = float(np.nansum(g.program.blocks["dwell_s"].to_numpy())) if "dwell_s" in g.program.blocks else 0.0
        return float(np.nansum(features["nominal_time_s"].to_numpy())) + dwell

    run.cam_s = _guarded(run, "CAM time", cam_from_features)


def _guarded(run: RecordingRun, what: str, fn: Callable[[], Any]) -> Any:
    """Run one stage on one recording; our errors and teammates' bugs are reported, never fatal."""
    try:
        return fn()
    except StageMissing as exc:
        run.notes.append(f"{what}: {exc}")
    except FeedlogError as exc:
        run.errors.append(f"{what} failed: {exc}")
    except Exception as exc:  # noqa: BLE001 - a bug in one stage must not stop the main job
        run.errors.append(f"{what} failed with an internal error ({type(exc).__name__}: {exc})")
    return None


def prepare_run(run: RecordingRun) -> RecordingRun:
    """Verify, align and simulate one recording: a task of `feedlog.execution` (may run on a worker)."""
    if not verify(run):
        return run
    run.gathered = _guarded(run, "gather", lambda: gather(
        run.recording, name=run.entry.name, catch_bugs=True, lenient=True,
        program=None if PROGRAM_ATTACHMENT in run.recording.attachments else run.entry.program_path,
        profile=run.entry.profile))
    if run.gathered is not None:
        for note in run.gathered.notes:
            (run.errors if "failed" in note else run.notes).append(note)
    _cam(run)
    if run.gathered is not None:
        # its times are taken (cam_s, sim_s) and its series and blocks stay in `gathered.inputs`: the rest of
        # the simulation (the planner's trajectory) is neither sent back from a worker nor held (peak memory)
        run.gathered.sim = None
    return run


def _release_training_tables(run: RecordingRun) -> None:
    """Trained: align's per-CL-point tables (`points`, the geometry and line block tables) are not needed
    again (the overlays take the block times, the report the cycle time): drop them (peak memory)."""
    aligned = run.gathered.aligned if run.gathered is not None else None
    if is_dataclass(aligned) and hasattr(aligned, "points"):
        run.gathered.aligned = replace(aligned, points=aligned.points.iloc[:0], geometry_blocks=None,
                                       line_blocks=None, geometry_blocks_base=None)


def trim_heap() -> None:
    """Give the heap memory freed so far back to the operating system (glibc's `malloc_trim`; elsewhere
    nothing): what torch's threads freed after training sits in their own arenas, which the main thread's
    next allocations do not reuse."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def view_of(run: RecordingRun) -> ViewData | None:
    """The recording's overlays: `run.data`, or built again from `run.gathered` (`keep_views=False`)."""
    if run.data is None and run.has_view and run.gathered is not None:
        return prepare_view(run.gathered.inputs)
    return run.data


def _sendable(run: RecordingRun) -> RecordingRun:
    """The run with absolute paths: a worker may run in another directory."""
    entry = replace(run.entry, path=Path(storage.absolute(run.entry.path)),
                    program_path=None if run.entry.program_path is None
                    else Path(storage.absolute(run.entry.program_path)))
    return replace(run, entry=entry)


def run_demo(config: DemoConfig) -> DemoResult:
    """Run the whole chain on `config.recordings`; outputs (plots, .rrd, models) go under `config.out`.

    The per-recording stages (verify, align, simulate) and the hybrid's simulations run on the backend
    `config.jobs`/`config.scheduler` choose (`feedlog.execution`); training, plots and .rrd files here.
    """
    with task_runner(jobs=config.jobs, scheduler=config.scheduler, progress=config.progress,
                     log=config.log) as runner:
        return _run_demo(config, runner)


def _run_demo(config: DemoConfig, runner: TaskRunner) -> DemoResult:
    log = config.log
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    stages = availability()
    for stage, reason in stages.items():
        if reason:
            log(f"stage {stage}: not available ({reason})")
    entries = discover(config.recordings)
    if not entries:
        raise FeedlogError(f"{config.recordings}: no recordings (*.mcap or {MANIFEST}) found")
    runs = [RecordingRun(entry=e) for e in entries]

    log(f"verify, align, simulate: {len(runs)} recording(s)")

    def ended(k: int, i: int, result) -> None:  # as each recording finishes, on any backend
        problems = (len(result.value.errors) if result.ok else 1)
        log(f"[{k}/{len(runs)}] {runs[i].entry.name}: verify, align, simulate"
            + (f": {problems} error(s)" if problems else ""))

    results = runner.run(prepare_run, [_sendable(r) for r in runs], desc="prepare", label=lambda r: r.entry.name,
                         on_done=ended)
    for i, result in enumerate(results):
        if result.ok:
            result.value.entry = runs[i].entry  # paths as the user gave them, for the report
            runs[i] = result.value
        else:
            runs[i].errors.append(f"verify, align, simulate failed: {result.error}")
    timings["verify_align_simulate"] = time.perf_counter() - t0

    training = None
    t1 = time.perf_counter()
    if config.train:
        training = train_models(runs, out_dir=config.out / "models", models=config.models, preset=config.preset,
                                log=log, runner=runner, progress=config.progress)
        if not config.keep_views:
            for run in runs:
                _release_training_tables(run)
        for run in runs:
            if run.gathered is not None and run.gathered.program is not None:
                for name, pred in predict_for(training, run).items():
                    run.models[name] = pred
    trim_heap()
    timings["train_predict"] = time.perf_counter() - t1

    t2 = time.perf_counter()
    for run in runs:
        if run.gathered is None:
            continue
        run.gathered.inputs.models = list(run.models.values())
        run.data = _guarded(run, "overlays", lambda run=run: prepare_view(run.gathered.inputs))
        _measured(run)
        _check_cycle_time(run)
        if run.data is not None:
            run.has_view, run.view_axes = True, run.data.axes
            if not config.keep_views:
                run.data = None
    timings["overlays"] = time.perf_counter() - t2
    timings["total"] = time.perf_counter() - t0
    return DemoResult(runs=runs, stages=stages, training=training, timings_s=timings)
