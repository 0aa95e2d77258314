"""`diagnose(recordings, profile)`: what the simulation gets wrong, the named cause, the extended profile, the gain.

1. Every recording is read, checked and aligned with its program (`cases.prepare_case`); all of them
   must come from one machine.
2. Evidence is gathered from the data alone (`evidence.gather`).
3. Per residual level (timing, feedback) the candidates of the hypothesis registry are selected
   greedily on held-out data (`select.select`): leave one recording out when there are several,
   held-out stretches of the one recording otherwise.
4. The accepted values extend the profile (`keys.with_values`); what remains systematic but no
   hypothesis explains is reported as unexplained, with where it lives (`unexplained`).
5. Before and after are measured at every level the data supports (`levels`).
"""

from __future__ import annotations

import os
import time
from contextlib import ExitStack
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from feedlog.diagnose import keys
from feedlog.diagnose.cases import Case, DiagnoseError, attached_profile, check_same_machine, prepare_case
from feedlog.diagnose.evidence import Evidence, gather
from feedlog.diagnose.fit import Scorer
from feedlog.diagnose.hypothesis import candidates, family
from feedlog.diagnose.select import Judged, SelectConfig, Selection, select, too_little_data
from feedlog.errors import FeedlogError
from feedlog.recording import Recording
from feedlog.profile import MachineProfile, load_profile

LEVELS = ("timing", "feedback", "line", "geometry")
AUTO_MIN_S = 10.0   # seconds of motion over two or more recordings from which `jobs=None` uses the cores


@dataclass(frozen=True)
class DiagnoseConfig:
    min_gain: float = 0.2              # share of the remaining held-out loss a cause must remove
    min_effect_pct: float = 1.0        # timing: held-out error must drop by this many percentage points
    min_effect_feedback_mm: float = 0.001
    min_effect_line_s: float = 0.002
    min_effect_geometry_mm: float = 0.01  # geometry: the joints' held-out RMS must drop by this much (mm)
    max_causes: int = 6
    families: tuple[str, ...] | None = None
    min_segment_s: float | None = None
    learned: bool = True               # fit a learned correction where a systematic residual is unexplained
    jobs: int | None = None            # processes (1: here, serially; None: the machine's cores for a large case,
    #                                    `scorer_processes`; more: the recordings prepared as tasks too)
    scheduler: str | None = None       # a Dask scheduler for them instead (feedlog.execution)
    calibrate: bool = False            # fit every axis limit the recordings constrain first (`calibrate`)

    @property
    def parallel(self) -> bool:
        """A task runner: the recordings prepared as tasks (and on a cluster the held-out fits)."""
        return self.scheduler is not None or (self.jobs is not None and self.jobs > 1)

    def scorer_processes(self, scorer: Scorer) -> int:
        """Processes the timing level's recordings are re-simulated on at once (`scorer_pool`): at most one
        per recording; `jobs` when given, else (None) the machine's cores when the case is large (two or
        more recordings, `AUTO_MIN_S` of motion; not inside a worker process of a task pool), else 1. On a cluster (`scheduler`) the held-out fits
        are the tasks instead, and each worker's scorer is serial."""
        if self.scheduler is not None or scorer.level != "timing":
            return 1
        n = len(scorer.groups)
        if self.jobs is not None:
            return max(1, min(self.jobs, n))
        import multiprocessing

        if multiprocessing.parent_process() is not None:  # a task's worker process (a pool's, a Dask worker's)
            return 1
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        return min(cores, n) if n >= 2 and scorer.data_s >= AUTO_MIN_S else 1

    def select_config(self, level: str, noise: float = 0.0) -> SelectConfig:
        """`noise`: the level's noise scale (feedback: position noise at rest; line: sampling period)."""
        effect = {"timing": self.min_effect_pct, "feedback": max(self.min_effect_feedback_mm, 2 * noise),
                  "line": max(self.min_effect_line_s, 2 * noise),
                  "geometry": max(self.min_effect_geometry_mm, 2 * noise)}[level]
        return SelectConfig(min_gain=self.min_gain, min_effect=effect, max_causes=self.max_causes)


@dataclass
class Finding:
    parameter: str
    profile_value: Any
    fitted_value: Any
    unit: str
    interval: tuple[float, float] | None
    gain_pct: float                 # share of the level's held-out loss it removed at its step
    error_before: float             # the level's held-out error before and after this cause
    error_after: float
    kind: str                       # parameter | mechanism
    level: str
    family: str
    evidence: str
    predicts: str
    alternatives: list[dict[str, Any]] = field(default_factory=list)
    fold_values: list[Any] = field(default_factory=list)
    where: str = ""                 # the block classes its change of the residual sits in
    scheme: str = ""                # how it was held out
    separated_by: dict[str, Any] | None = None  # with alternatives: the recording that would tell them apart

    def as_dict(self) -> dict[str, Any]:
        """The finding as the `--json` object has it (`summary.clean` makes it JSON-ready)."""
        return {"parameter": self.parameter, "profile_value": self.profile_value, "fitted_value": self.fitted_value,
                "unit": self.unit, "interval": None if self.interval is None else list(self.interval),
                "gain_pct": self.gain_pct, "error_before": self.error_before, "error_after": self.error_after,
                "kind": self.kind, "level": self.level, "family": self.family, "evidence": self.evidence,
                "predicts": self.predicts, "alternatives": self.alternatives, "fold_values": list(self.fold_values),
                "where": self.where, "held_out": self.scheme,
                **({"separated_by": self.separated_by} if self.alternatives else {})}


@dataclass
class Diagnosis:
    profile: MachineProfile
    extended: MachineProfile
    cases: list[Case]
    evidence: Evidence
    selections: dict[str, Selection]
    scorers: dict[str, Scorer]
    findings: list[Finding]
    unexplained: list[dict[str, Any]] = field(default_factory=list)
    levels: dict[str, Any] = field(default_factory=dict)
    held_out: dict[str, Any] = field(default_factory=dict)
    where: dict[str, Any] = field(default_factory=dict)
    timings_s: dict[str, float] = field(default_factory=dict)
    noise_floor: dict[str, Any] = field(default_factory=dict)
    profile_out: str | None = None
    sims: dict[str, list[Any]] = field(default_factory=dict)
    learned_model: Any = None
    calibration: Any = None            # `calibrate.Calibration` with --calibrate
    changes: list[Any] = field(default_factory=list)   # `changes.Change`: a parameter that changed mid-session

    @property
    def diff(self) -> list[tuple[str, Any, Any]]:
        """(key, given, extended) for every profile value the diagnosis changed."""
        return keys.diff(self.profile, self.extended)

    @property
    def recordings(self) -> list[str]:
        return [c.source for c in self.cases]


def load_cases(sources: Sequence[str | Path | Recording], profile: MachineProfile | str | Path | None, *,
               program: Any = None, lenient: bool = False, runner: Any = None) -> tuple[MachineProfile, list[Case]]:
    """Read and align every recording (as tasks on `runner` when given and the sources are files); the
    profile is the given one or the one the recordings carry."""
    if not sources:
        raise DiagnoseError("no recordings to diagnose")
    if profile is None:
        from feedlog.ingest import read_recording

        first = sources[0] if isinstance(sources[0], Recording) else read_recording(sources[0])
        prof = attached_profile(first, Path(first.source).stem)
        if prof is None:
            raise DiagnoseError(f"{first.source}: carries no machine profile; give one with --profile")
        sources = [first, *sources[1:]]
    else:
        prof = profile if isinstance(profile, MachineProfile) else load_profile(profile)
    if runner is not None and len(sources) > 1 and not any(isinstance(s, Recording) for s in sources):
        from feedlog import storage
        from feedlog.diagnose.parallel import PrepareItem, prepare_task

        prog = program
        if prog is not None and not hasattr(prog, "blocks"):  # parsed once here, sent as data
            from feedlog.toolpath import load_program

            prog = load_program(Path(prog), lenient=lenient)
        items = [PrepareItem(source=storage.absolute(str(s)), profile=prof, program=prog, lenient=lenient)
                 for s in sources]
        results = runner.run(prepare_task, items, desc="prepare", label=lambda i: Path(i.source).name)
        failed = [r for r in results if not r.ok]
        if failed:
            raise DiagnoseError(failed[0].error or f"{failed[0].label}: could not be prepared")
        cases = [r.value for r in results]
    else:
        cases = [prepare_case(s, prof, program=program, lenient=lenient) for s in sources]
    check_same_machine(cases)
    names = [c.name for c in cases]
    if len(set(names)) != len(names):
        raise DiagnoseError(f"two recordings share the name {next(n for n in names if names.count(n) > 1)!r}")
    return prof, cases


def timing_error(scorer: Scorer, *, floor: bool = True) -> Callable[[np.ndarray, list[int]], float]:
    """RMS-based share of misplaced time (%) above the noise floor: 100 sqrt(n (sum r^2 - floor)) / T over
    the units' segments (equals sum |r| / T when every segment is off by the same amount)."""
    def error(losses: np.ndarray, units: list[int]) -> float:
        n = total = 0.0
        for u in units:
            unit = scorer.units[u]
            w = scorer.weights[unit.case][unit.lo:unit.hi]
            n += float(w.sum())
            total += float((scorer.segments[unit.case].measured_s[unit.lo:unit.hi] * w).sum())
        excess = float(np.sum(losses[units])) - (float(np.sum(scorer.floor[units])) if floor else 0.0)
        return 100.0 * float(np.sqrt(n * max(excess, 0.0))) / total if total > 0 else 0.0
    return error


def feedback_error(scorer: Scorer, *, floor: bool = True) -> Callable[[np.ndarray, list[int]], float]:
    """RMS of the feedback position residual above its noise, over the units' samples and joints (mm / deg)."""
    def error(losses: np.ndarray, units: list[int]) -> float:
        count = sum((scorer.units[u].hi - scorer.units[u].lo) * scorer.cases[scorer.units[u].case].feedback.cmd.shape[1]
                    for u in units)
        excess = float(np.sum(losses[units])) - (float(np.sum(scorer.floor[units])) if floor else 0.0)
        return float(np.sqrt(max(excess, 0.0) / count)) if count else 0.0
    return error


def line_error(scorer: Scorer, *, floor: bool = True) -> Callable[[np.ndarray, list[int]], float]:
    """RMS of the line stream's block-change offset residual above its resolution (s)."""
    def error(losses: np.ndarray, units: list[int]) -> float:
        count = sum(scorer.units[u].hi - scorer.units[u].lo for u in units)
        excess = float(np.sum(losses[units])) - (float(np.sum(scorer.floor[units])) if floor else 0.0)
        return float(np.sqrt(max(excess, 0.0) / count)) if count else 0.0
    return error


def geometry_error(scorer: Scorer, *, floor: bool = True) -> Callable[[np.ndarray, list[int]], float]:
    """RMS of the linear joints' residual (kinematics of the recorded axes minus the recorded joints)
    above its resolution (mm)."""
    def error(losses: np.ndarray, units: list[int]) -> float:
        count = 3 * sum(scorer.units[u].hi - scorer.units[u].lo for u in units)
        excess = float(np.sum(losses[units])) - (float(np.sum(scorer.floor[units])) if floor else 0.0)
        return float(np.sqrt(max(excess, 0.0) / count)) if count else 0.0
    return error


def level_error(scorer: Scorer, *, floor: bool = True) -> Callable[[np.ndarray, list[int]], float]:
    return {"timing": timing_error, "feedback": feedback_error, "line": line_error,
            "geometry": geometry_error}[scorer.level](scorer, floor=floor)


def feedback_noise(cases: Sequence[Case]) -> float:
    """Noise of the feedback positions at rest (the first 0.1 s), the largest over the recordings."""
    from feedlog.align.blocks import rest_noise

    out = 0.0
    for c in cases:
        if c.feedback is not None:
            out = max(out, rest_noise(c.feedback.t_ns, c.feedback.fb))
    return out


def diagnose(sources: Sequence[str | Path | Recording], profile: MachineProfile | str | Path | None = None, *,
             program: Any = None, config: DiagnoseConfig | None = None, lenient: bool = False,
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Diagnose `profile` (default: the one the recordings carry) on the recordings."""
    cfg = config or DiagnoseConfig()
    with ExitStack() as stack:  # the task runner and the scorers' processes, closed however this ends
        runner = None
        if cfg.parallel:
            from feedlog.execution import task_runner

            runner = stack.enter_context(task_runner(jobs=cfg.jobs, scheduler=cfg.scheduler, progress=False,
                                                     log=progress or (lambda _msg: None)))
        return _diagnose(sources, profile, program, cfg, lenient, progress, runner=runner, stack=stack)


def _diagnose(sources, profile, program, cfg: DiagnoseConfig, lenient: bool, progress, *, runner,
              stack: ExitStack) -> Diagnosis:
    import uuid

    laps: dict[str, float] = {}
    t0 = time.perf_counter()
    say = progress or (lambda _msg: None)
    token = uuid.uuid4().hex
    prof, cases = load_cases(sources, profile, program=program, lenient=lenient, runner=runner)
    laps["prepare"] = time.perf_counter() - t0
    say(f"{len(cases)} recording(s) aligned")
    ev = gather(cases, prof)
    given, cal = prof, None
    if cfg.calibrate:  # every axis limit first, all together; the causes are then looked for on top of it
        from feedlog.diagnose.calibrate import calibrate

        t1 = time.perf_counter()
        cal = calibrate(prof, cases, ev, min_segment_s=cfg.min_segment_s, progress=say)
        prof = cal.profile
        laps["calibrate"] = time.perf_counter() - t1
    hyps = [replace(h, seeds=(*h.seeds, *family(h.family).suggest(ev, h.key, h.baseline)))
            for h in candidates(prof, cases, families=cfg.families)]
    selections: dict[str, Selection] = {}
    scorers: dict[str, Scorer] = {}
    built: dict[str, Scorer] = {}
    build_s: dict[str, float] = {}
    for level in LEVELS:  # every level's data first: too little of it everywhere is refused before any fit
        t1 = time.perf_counter()
        try:
            built[level] = Scorer(prof, cases, level, min_segment_s=cfg.min_segment_s)
        except FeedlogError as exc:
            raise DiagnoseError(f"cannot simulate the recordings' programs on profile {prof.name!r}: {exc}") from None
        build_s[level] = time.perf_counter() - t1
    _enough_data(built, hyps)
    for level in LEVELS:
        t1 = time.perf_counter() - build_s[level]
        level_hyps = [h for h in hyps if h.level == level]
        scorer = built[level]
        if not scorer.units:
            continue
        scorers[level] = scorer
        error = level_error(scorer)
        noise = {"feedback": feedback_noise(cases), "line": max(c.period_s for c in cases)}.get(level, 0.0)
        many = None
        processes = cfg.scorer_processes(scorer)
        if processes > 1:  # each re-simulation's recordings shared out over the cores
            from feedlog.diagnose.scorer_pool import ScorerPool

            stack.enter_context(ScorerPool(scorer, processes))
            say(f"{level}: {len(scorer.groups)} recordings re-simulated on {processes} processes")
        elif runner is not None and cfg.scheduler is not None:
            from feedlog.diagnose.parallel import held_out_on

            many = held_out_on(runner, f"{token}:{level}", scorer, cfg.min_segment_s)
        selections[level] = select(scorer, level_hyps, error=error, evidence=ev,
                                   cfg=cfg.select_config(level, noise), progress=say, held_out_many=many)
        laps[level] = time.perf_counter() - t1
    changes = []
    if "timing" in selections:  # a dial turned mid-session: a step, not one value averaged over it
        from feedlog.diagnose.changes import find_changes

        t1 = time.perf_counter()
        changes = find_changes(scorers["timing"], selections["timing"].model, [h for h in hyps if h.level == "timing"],
                               min_gain=cfg.min_gain, min_effect_pct=cfg.min_effect_pct)
        laps["changes"] = time.perf_counter() - t1
    stepped = {c.parameter for c in changes}
    model: dict[str, Any] = {}
    for sel in selections.values():
        model.update({k: v for k, v in sel.model.items() if k not in stepped})
    extended = keys.with_values(prof, model, name=f"{given.name}-diagnosed") if model else prof.replace(
        name=f"{given.name}-diagnosed")
    findings = [_finding(step.chosen, sel, scorers[level], ev, level_error(scorers[level]))
                for level, sel in selections.items() for step in sel.steps if step.chosen.key not in stepped]
    dx = Diagnosis(profile=given, extended=extended, cases=cases, evidence=ev, selections=selections,
                   scorers=scorers, findings=findings, noise_floor=_noise_floor(scorers, cfg, cases), calibration=cal,
                   changes=changes)
    t2 = time.perf_counter()
    from feedlog.diagnose.levels import measure_levels
    from feedlog.diagnose.unexplained import find_unexplained

    dx.levels, dx.held_out, dx.where = measure_levels(dx)
    laps["levels"] = time.perf_counter() - t2
    t3 = time.perf_counter()
    dx.unexplained = find_unexplained(dx, learned=cfg.learned, min_effect_pct=cfg.min_effect_pct,
                                      min_gain=cfg.min_gain, progress=say)
    laps["unexplained"] = time.perf_counter() - t3
    laps["total"] = time.perf_counter() - t0
    dx.timings_s = {k: round(v, 3) for k, v in laps.items()}
    return dx


def _enough_data(scorers: dict[str, Scorer], hyps) -> None:
    """Refuse (DiagnoseError) when no level holds the data any of its hypotheses needs: too little data
    is said, not fitted."""
    short = []
    for level, scorer in scorers.items():
        needs = [h.needs for h in hyps if h.level == level]
        if not needs or not scorer.units:
            continue
        why = too_little_data(scorer, min(needs))
        if why is None:
            return
        short.append(why.removeprefix("too little data: ") + ("" if level == "timing" else f" ({level})"))
    if short:
        raise DiagnoseError(f"too little data: {'; '.join(short)}: record more of the program (longer or more "
                            "recordings) before naming a cause")


def _noise_floor(scorers: dict[str, Scorer], cfg: DiagnoseConfig, cases: Sequence[Case]) -> dict[str, Any]:
    """What the data resolves (the loss a perfect model leaves, as the level's error) and what counts."""
    out: dict[str, Any] = {"timing_pct": None, "feedback_mm": None, "min_effect_pct": cfg.min_effect_pct,
                           "min_gain": cfg.min_gain}
    if "timing" in scorers:
        sc = scorers["timing"]
        units = list(range(len(sc.units)))
        out["timing_pct"] = timing_error(sc, floor=False)(sc.floor, units)
        out["sampling_period_s"] = sorted({round(c.period_s, 6) for c in cases})
    if "feedback" in scorers:
        sc = scorers["feedback"]
        out["feedback_mm"] = feedback_error(sc, floor=False)(sc.floor, list(range(len(sc.units))))
        out["min_effect_feedback_mm"] = max(cfg.min_effect_feedback_mm, 2 * feedback_noise(cases))
    if "line" in scorers:
        sc = scorers["line"]
        out["line_s"] = line_error(sc, floor=False)(sc.floor, list(range(len(sc.units))))
        out["min_effect_line_s"] = max(cfg.min_effect_line_s, 2 * max(c.period_s for c in cases))
    if "geometry" in scorers:
        sc = scorers["geometry"]
        out["geometry_mm"] = geometry_error(sc, floor=False)(sc.floor, list(range(len(sc.units))))
        out["min_effect_geometry_mm"] = cfg.min_effect_geometry_mm
    return out


def _finding(j: Judged, sel: Selection, scorer: Scorer, ev: Evidence, error) -> Finding:
    hyp = j.held.hyp
    value = sel.model.get(hyp.key, j.held.value)
    alts = [{"parameter": a.key, "fitted_value": a.held.value, "unit": a.held.hyp.unit,
             "gain_pct": 100 * a.held.gain} for a in _alternatives(sel, hyp.key)]
    separated = None
    if alts and hyp.level == "timing":  # which recording would tell the equally good ones apart
        from feedlog.diagnose.separate import separating_program

        rest = {k: v for k, v in sel.model.items() if k not in hyp.keys}
        alt = next(a for a in _alternatives(sel, hyp.key))
        base = keys.with_values(scorer.profile, rest) if rest else scorer.profile
        separated = separating_program(base, hyp.values(value), alt.held.hyp.values(alt.held.value))
    return Finding(parameter=hyp.key, profile_value=hyp.baseline, fitted_value=_round_value(hyp, value),
                   unit=hyp.unit, interval=j.held.interval, gain_pct=100 * j.held.gain,
                   error_before=j.error_before, error_after=j.error_after, kind=hyp.kind, level=hyp.level,
                   family=hyp.family, evidence=family(hyp.family).describe(ev, hyp.key, value), predicts=hyp.predicts,
                   alternatives=alts, fold_values=list(j.held.extra.get("fold_fits", [])),
                   scheme=j.held.extra.get("scheme", ""), separated_by=separated)


def _alternatives(sel: Selection, key: str) -> list[Judged]:
    for step in sel.steps:
        if step.chosen.key == key:
            return step.alternatives
    return []


def _round_value(hyp, value: Any) -> Any:
    if hyp.scale == "int":
        return int(round(value))
    return float(value) if isinstance(value, (int, float, np.floating)) else value
