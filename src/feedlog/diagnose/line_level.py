"""Diagnosis from the line stream alone: block-level times, session events, the causes they can see.

Most monitoring data (MTConnect, OPC UA) gives the executing block, the feed and the spindle, and no
positions. This is the block level of Chien et al. (per-block times; docs/diagnose.md): a recorded line
change is a block boundary, so the time between two recorded line changes is the time of the program
lines between them, to be compared with the simulation's. What it does:

1. The session (`align.line_session`): numbering, the program lines the data can place, the events
   (tool changes, stops, waits on M codes, standstills) with their times.
2. Intervals between consecutive placed line changes: measured time (events inside taken out: they are
   no motion) against the simulated time of those lines, split into feed and rapid time. Lines the
   simulation gives no time, and intervals over runs the data cannot place, are left out.
3. The causes the block level can see: measured = k_feed,s x feed time (one k per tool section s: the
   feed override an operator sets per tool) + k_rapid x rapid time, each k the median ratio of the
   intervals of that kind alone (with a recorded rapid override dial, the `override` stream, also the
   rapid factor of the stretches where it read 100 %, and the dial's time below 100 % with the events it
   covered); and the tool change time (the recorded M6 events' median). Fitted on
   every other interval and judged on the rest (held out), then on all.
4. The extended profile (`sim.feed_override`, `sim.rapid_override`, `sim.tool_change`) and the cycle
   before and after: measured, simulated, the share that is tool change and other standstill, what
   remains and why.

What the block level cannot see without positions is said in the report (`BLIND`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from feedlog.align.attached import attached_profile, attached_program
from feedlog.align.line_session import Session, session_lines
from feedlog.diagnose import keys
from feedlog.errors import AlignmentError, FeedlogError
from feedlog.profile import MachineProfile
from feedlog.recording import Recording
from feedlog.toolpath.schema import RAPID

MIN_INTERVALS = 8    # fewer placed intervals: nothing is fitted
MIN_CHANGE = 0.02    # an override is proposed only when it differs from 1 by this much (the sampling's noise)
BLIND = ("corner speeds, acceleration and jerk limits inside a stretch of blocks (they only change how long "
         "the stretch takes, which the feed factor absorbs)",
         "path deviation and blending tolerance (G64 P): where the tool went",
         "following lag, feedback delay and servo tuning (command against feedback positions)",
         "the logger's latency below the line sampling period, and axis-by-axis velocity limits",
         "what each short block takes inside a stretch: the line stream shows one line in several")


class LineDiagnoseError(FeedlogError):
    pass


@dataclass
class LineDiagnosis:
    recording: str
    program: str
    profile: MachineProfile
    extended: MachineProfile
    session: Session
    figures: dict[str, Any]
    fit: dict[str, Any]
    warnings: list[str] = field(default_factory=list)

    @property
    def values(self) -> dict[str, float]:
        return self.fit["values"]


def line_stream_only(paths: list[str]) -> bool:
    """Whether every recording has a line stream and no positions (read from the MCAP summary, cheaply;
    a file without one, or not MCAP, is left to the full diagnosis, which reads and checks it)."""
    from mcap.reader import make_reader

    for path in paths:
        try:
            with open(path, "rb") as fh:
                summary = make_reader(fh).get_summary()
        except Exception:   # noqa: BLE001 - any unreadable file: the full path reads it and says why
            return False
        topics = {c.topic for c in summary.channels.values()} if summary is not None else None
        if not topics or "axes" in topics or "line" not in topics:
            return False
    return True


def _line_times(sim, program) -> pd.DataFrame:
    """Per program line with simulated motion: start (s) and its feed and rapid time."""
    b = sim.blocks.copy()
    kinds = program.blocks.set_index("block")["kind"].astype(str)
    b["rapid"] = b["block"].map(kinds).eq(RAPID).to_numpy()
    b["t0"] = b["t_start_ns"] / 1e9
    g = b.groupby("line")
    out = pd.DataFrame({"t0": g["t0"].min(),
                        "feed_s": g.apply(lambda x: x.loc[~x["rapid"], "duration_s"].sum(), include_groups=False),
                        "rapid_s": g.apply(lambda x: x.loc[x["rapid"], "duration_s"].sum(), include_groups=False)})
    return out.sort_index()


def intervals(session: Session, lines: pd.DataFrame, tool_lines: list[int]) -> pd.DataFrame:
    """Consecutive placed runs whose program lines both have simulated motion and go forward: measured
    seconds (events inside taken out), simulated feed and rapid seconds of the lines in between, and the
    tool section (how many program M6 lines lie before)."""
    runs = session.runs
    pl = runs["program_line"].to_numpy(np.float64)
    ok = np.isfinite(pl) & np.isin(np.nan_to_num(pl, nan=-1).astype(np.int64), lines.index.to_numpy())
    rows = np.flatnonzero(ok)
    start = runs["t_start_ns"].to_numpy(np.int64)
    ev = session.events
    ev0 = ev["t_start_ns"].to_numpy(np.int64) if len(ev) else np.empty(0, np.int64)
    ev1 = ev["t_end_ns"].to_numpy(np.int64) if len(ev) else np.empty(0, np.int64)
    evs = ev["duration_s"].to_numpy(np.float64) if len(ev) else np.empty(0)
    # cumulative simulated feed / rapid time before each line (lines between a and b: cum[b] - cum[a])
    before_feed = pd.Series(np.r_[0.0, lines["feed_s"].cumsum().to_numpy()[:-1]], index=lines.index)
    before_rapid = pd.Series(np.r_[0.0, lines["rapid_s"].cumsum().to_numpy()[:-1]], index=lines.index)
    out = []
    offs = session.line_map.offsets
    for i, j in zip(rows[:-1], rows[1:]):
        pa, pb = int(pl[i]), int(pl[j])
        if pb <= pa or not np.isfinite(pl[i:j + 1]).all():   # backwards, or over runs the data cannot place
            continue
        if len(offs) == len(pl) and offs[i] != offs[j]:    # lines inserted or removed in between: no block time
            continue
        t0, t1 = start[i], start[j]
        inside = float(evs[(ev0 >= t0) & (ev1 <= t1)].sum())
        out.append({"from_line": pa, "to_line": pb, "measured_s": (t1 - t0) / 1e9 - inside, "events_s": inside,
                    "feed_s": float(before_feed[pb] - before_feed[pa]),
                    "rapid_s": float(before_rapid[pb] - before_rapid[pa]),
                    "section": int(np.searchsorted(tool_lines, pa)), "t0_ns": int(t0), "t1_ns": int(t1)})
    return pd.DataFrame(out, columns=["from_line", "to_line", "measured_s", "events_s", "feed_s", "rapid_s", "section",
                                      "t0_ns", "t1_ns"])


MIN_SIM_S = 0.1      # intervals the simulation gives less time than this say little against the sampling
FULL_DIAL = 0.995    # a recorded override dial at or above this reads 100 %


def dial(recording: Recording, column: str, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """The recorded override dial (`override` stream, a fraction) over each [t0, t1): its held value
    averaged over the time; NaN without the stream (or before its first value)."""
    table = recording.streams.get("override")
    out = np.full(len(t0), np.nan)
    if table is None or column not in table.columns or not len(table):
        return out
    ts, v = table["t_ns"].to_numpy(np.int64), table[column].to_numpy(np.float64)
    for k, (a, b) in enumerate(zip(np.asarray(t0, np.int64), np.asarray(t1, np.int64))):
        a = max(int(a), int(ts[0]))         # the dial's value is known from its first sample on
        if b <= a:
            continue
        i = int(np.searchsorted(ts, a, side="right")) - 1
        j = int(np.searchsorted(ts, b, side="left"))
        edges = np.r_[a, ts[i + 1:j], b]
        out[k] = float(np.sum(v[i:j] * np.diff(edges)) / (b - a))
    return out


def rapid_dial_figures(recording: Recording, session: Session) -> dict[str, Any] | None:
    """What the recorded rapid override dial says over the run (None without one): its lowest value,
    the time the dial stood below 100 %, when it last came up to 100 % (s from the first run's start),
    and the events that ran with it below 100 % (their mean dial)."""
    table = recording.streams.get("override")
    if table is None or "rapid_override" not in table.columns or not len(table):
        return None
    runs = session.runs
    t_start, t_end = int(runs["t_start_ns"].iloc[0]), int(runs["t_end_ns"].iloc[-1])
    ts, v = table["t_ns"].to_numpy(np.int64), table["rapid_override"].to_numpy(np.float64)
    edges = np.clip(np.r_[ts, t_end], t_start, t_end)
    below = float(np.diff(edges)[v < FULL_DIAL].sum()) / 1e9
    inside = (ts < t_end) & (np.r_[ts[1:], t_end] > t_start)
    low = np.flatnonzero(inside & (v < FULL_DIAL))
    full_from = None
    if len(low) and low[-1] + 1 < len(ts):
        full_from = (int(ts[low[-1] + 1]) - t_start) / 1e9
    ev = session.events
    slow: list[dict[str, Any]] = []
    if len(ev):
        mean = dial(recording, "rapid_override", ev["t_start_ns"].to_numpy(np.int64), ev["t_end_ns"].to_numpy(np.int64))
        slow = [{"kind": e["kind"], "recorded_line": e["recorded_line"], "duration_s": e["duration_s"],
                 "rapid_override_mean": m} for e, m in zip(ev.to_dict("records"), mean) if np.isfinite(m) and m < FULL_DIAL]
    return {"min": float(v[inside].min()) if inside.any() else None, "below_full_s": below,
            "full_from_s": full_from, "events_below_full": slow}


def _factors(iv: pd.DataFrame, sections: list[int]) -> tuple[list[float], float]:
    """Median measured/simulated ratio of the pure feed intervals per tool section, and of the pure
    rapid intervals (NaN where there are none): medians, as an override dial turned for a while (a
    rapid override at the first approach) moves a mean, not a median."""
    feed = iv[(iv["rapid_s"] == 0) & (iv["feed_s"] >= MIN_SIM_S)]
    rapid = iv[(iv["feed_s"] == 0) & (iv["rapid_s"] >= MIN_SIM_S)]
    k_feed = [float((g["measured_s"] / g["feed_s"]).median()) if len(g := feed[feed["section"] == s]) else np.nan
              for s in sections]
    k_rapid = float((rapid["measured_s"] / rapid["rapid_s"]).median()) if len(rapid) else np.nan
    return k_feed, k_rapid


def _predict(iv: pd.DataFrame, sections: list[int], k_feed: list[float], k_rapid: float) -> np.ndarray:
    kf = pd.Series(np.nan_to_num(k_feed, nan=1.0), index=sections).reindex(iv["section"]).fillna(1.0).to_numpy()
    return kf * iv["feed_s"].to_numpy() + (1.0 if np.isnan(k_rapid) else k_rapid) * iv["rapid_s"].to_numpy()


def fit_factors(iv: pd.DataFrame) -> dict[str, Any]:
    """Time factors (measured / simulated) of feed time per tool section and of rapid time
    (`_factors`); held out: fitted on even intervals, judged on odd ones (mean absolute error over the
    measured time)."""
    sections = sorted(iv["section"].unique().tolist())
    y = iv["measured_s"].to_numpy()
    sim = (iv["feed_s"] + iv["rapid_s"]).to_numpy()
    even = np.arange(len(iv)) % 2 == 0
    kf_half, kr_half = _factors(iv[even], sections)
    odd = iv[~even]
    before = float(np.abs(y[~even] - sim[~even]).sum() / y[~even].sum())
    after = float(np.abs(y[~even] - _predict(odd, sections, kf_half, kr_half)).sum() / y[~even].sum())
    k_feed, k_rapid = _factors(iv, sections)
    full = None
    if "rapid_override" in iv.columns and np.isfinite(iv["rapid_override"]).any():
        # with a recorded rapid dial: the rapid factor of the stretches where it read 100 % (the machine's own)
        _, full = _factors(iv[~(iv["rapid_override"] < FULL_DIAL)], sections)
    return {"sections": sections, "k_feed": k_feed, "k_rapid": k_rapid, "k_rapid_full_dial": full,
            "held_out_error_before_pct": 100 * before, "held_out_error_after_pct": 100 * after,
            "intervals": int(len(iv)), "measured_s": float(y.sum()), "simulated_s": float(sim.sum()),
            "fitted_s": float(_predict(iv, sections, k_feed, k_rapid).sum())}


def stretch_figures(session: Session, iv: pd.DataFrame, fit: dict[str, Any]) -> list[dict[str, Any]]:
    """The stretches placed between the first mismatch and the anchor (`line_stretches`): their lines and
    offset, and per stretch the measured seconds of its intervals (events out) against the simulated
    ones and the ones the fitted factors predict."""
    out = []
    pred = _predict(iv, fit["sections"], fit["k_feed"], fit["k_rapid"]) if len(iv) else np.empty(0)
    for st in session.line_map.stretches:
        lo, hi = st["program_lines"]
        inside = (iv["from_line"] >= lo).to_numpy() & (iv["to_line"] <= hi).to_numpy() if len(iv) else np.empty(0, bool)
        part = iv[inside]
        out.append({**st, "intervals": int(inside.sum()), "measured_s": float(part["measured_s"].sum()),
                    "simulated_s": float((part["feed_s"] + part["rapid_s"]).sum()),
                    "fitted_s": float(pred[inside].sum()),
                    "blocks": [{"from_line": int(r["from_line"]), "to_line": int(r["to_line"]),
                                "recorded_from_line": int(r["from_line"]) + st["offset"],
                                "measured_s": float(r["measured_s"]), "simulated_s": float(r["feed_s"] + r["rapid_s"])}
                               for r in part.to_dict("records")]})
    return out


def diagnose_lines(recording: Recording, profile: MachineProfile | str | None, program: Any, *,
                   lenient: bool = False, numbering: str = "auto") -> LineDiagnosis:
    """See the module docstring."""
    from feedlog.sim import simulate

    name = recording.source or "recording"
    prof = attached_profile(recording, profile)
    if prof is None:
        raise LineDiagnoseError(f"{name}: carries no machine profile; give one with --profile")
    try:
        prog = attached_program(recording, program, lenient)
    except AlignmentError as exc:
        raise LineDiagnoseError(str(exc)) from None
    stream = recording.streams.get("line")
    if stream is None or "line" not in stream.columns or len(stream) < 2:
        raise LineDiagnoseError(f"{name}: no positions ('axes') and no line stream: nothing to diagnose")
    _, _, session = session_lines(recording, prog, prof, stream["t_ns"].to_numpy(np.int64),
                                  stream["line"].to_numpy(), numbering)
    motion_only = {"tool_change": False}
    sim = simulate(prog, prof, mechanisms=motion_only)
    lines = _line_times(sim, prog)
    codes = prog.blocks["mcodes"].fillna("").astype(str).str.contains(r"(?i)\bM0*6\b")
    tool_lines = sorted(int(v) for v in prog.blocks.loc[codes, "line"] if v > lines.index.min())
    iv = intervals(session, lines, tool_lines)
    iv["rapid_override"] = dial(recording, "rapid_override", iv["t0_ns"].to_numpy(), iv["t1_ns"].to_numpy())
    if len(iv) < MIN_INTERVALS:
        raise LineDiagnoseError(f"{name}: only {len(iv)} stretches between recorded line changes could be placed "
                                f"on {prog.name}; at least {MIN_INTERVALS} are needed")
    fit = fit_factors(iv)
    ev = session.events
    tool = ev[ev["kind"] == "tool change"]["duration_s"] if len(ev) else pd.Series(dtype=float)
    values: dict[str, float] = {}
    fs = lines["feed_s"].groupby(np.searchsorted(tool_lines, lines.index.to_numpy())).sum()
    weights = np.array([fs.get(s, 0.0) for s in fit["sections"]])
    known = np.isfinite(fit["k_feed"]) & (weights > 0)
    k_feed = float(np.average(np.asarray(fit["k_feed"])[known], weights=weights[known])) if known.any() else np.nan
    if np.isfinite(k_feed) and k_feed > 0 and abs(1.0 / k_feed - 1.0) >= MIN_CHANGE:
        values["sim.feed_override.override"] = round(1.0 / k_feed, 4)
    if np.isfinite(fit["k_rapid"]) and fit["k_rapid"] > 0 and abs(1.0 / fit["k_rapid"] - 1.0) >= MIN_CHANGE:
        values["sim.rapid_override.override"] = round(min(1.0 / fit["k_rapid"], 10.0), 4)
    if len(tool):
        values["sim.tool_change.time_s"] = round(float(tool.median()), 3)
    fit["values"] = values
    extended = keys.with_values(prof, values, name=f"{prof.name}+line-diagnosis")
    after = simulate(prog, extended)
    measured = float(session.runs["t_end_ns"].iloc[-1] - session.runs["t_start_ns"].iloc[0]) / 1e9
    totals = {k: float(v) for k, v in ev.groupby("kind")["duration_s"].sum().items()} if len(ev) else {}
    not_tool = sum(v for k, v in totals.items() if k != "tool change")
    figures = {
        "measured_cycle_s": measured,
        "simulated_cycle_s": float(sim.cycle_time_s),
        "events_s": totals,
        "tool_change_share_pct": 100 * totals.get("tool change", 0.0) / measured,
        "standstill_share_pct": 100 * not_tool / measured,
        "motion_measured_s": measured - sum(totals.values()),
        "simulated_after_s": float(after.cycle_time_s),
        "predicted_after_s": float(after.cycle_time_s) + not_tool,
        "line_period_s": float(np.median(np.diff(stream["t_ns"].to_numpy(np.int64)))) / 1e9,
    }
    figures["rapid_override"] = rapid_dial_figures(recording, session)
    # the motion time (events out) compared stretch by stretch between placed line changes
    figures["timed_per_block_s"] = float(iv["measured_s"].sum())
    figures["timed_per_block_pct"] = 100 * float(iv["measured_s"].sum()) / figures["motion_measured_s"]
    figures["stretches"] = stretch_figures(session, iv, fit)
    runs = session.runs
    figures["unplaced_s"] = float(runs.loc[runs["program_line"].isna(), "dur_s"].sum())
    figures["remaining_s"] = measured - figures["predicted_after_s"]
    figures["error_before_pct"] = 100 * (figures["simulated_cycle_s"] - measured) / measured
    figures["error_after_pct"] = 100 * (figures["predicted_after_s"] - measured) / measured
    return LineDiagnosis(recording=name, program=prog.name, profile=prof, extended=extended, session=session,
                         figures=figures, fit=fit, warnings=list(session.warnings))


__all__ = ["BLIND", "LineDiagnosis", "LineDiagnoseError", "diagnose_lines", "fit_factors", "intervals",
           "stretch_figures"]
