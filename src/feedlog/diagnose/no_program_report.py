"""`feedlog diagnose REC` with no program (`no_program.measure`): the summary lines, the `--json` object,
and the output folder (report.md, diagnose.json, profile.toml where the machine is a 3-axis one the data
constrains), written whole or not at all (`storage.publish_dir`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from feedlog.diagnose.no_program import DataOnly, carries_program, measure, read_all
from feedlog.errors import FeedlogError

BASE_PROFILE = "generic-xyz"


def applies(args: argparse.Namespace) -> bool:
    """`feedlog diagnose` runs this path: no --program given and no recording carries one."""
    return args.program is None and not any(carries_program(p) for p in args.recordings)


def _num(v: float | None, digits: int = 1) -> str:
    return "-" if v is None else f"{v:,.{digits}f}"


def summary_lines(dx: DataOnly) -> list[str]:
    names = ", ".join(Path(r).name for r in dx.recordings)
    every = "" if not dx.period_s else (f"{dx.period_s:.3g} s" if dx.period_s >= 1 else f"{dx.period_s * 1000:.3g} ms")
    out = [f"diagnose without a program: {names} ({dx.duration_s:.1f} s"
           + (f", positions every {every})" if every else ", no positions)"),
           "  nothing is simulated (no program): what the data alone says, as lower bounds unless marked 'limit'"]
    for a in dx.axes.values():
        u = a.unit
        speed = f"speed peak {_num(a.peak_speed, 2)} {u}/s"
        if a.held_speed is not None:
            speed += (f", held {_num(a.held_speed.value, 2)} {u}/s ({a.held_speed.count}x, "
                      f"{a.held_speed.seconds:.2f} s" + (", alone" if a.held_speed.alone else "") + ")")
        if a.speed_from != "positions":
            speed += f" [from the {a.speed_from}]"
        acc = "no acceleration (samples too sparse or too few)" if a.peak_acc is None else \
            f"acceleration peak {_num(a.peak_acc)} {u}/s^2"
        if a.held_acc is not None:
            acc += (f", held {_num(a.held_acc.value)} {u}/s^2 ({a.held_acc.count}x)"
                    + (" = limit" if a.acc_limit else ""))
        out.append(f"  {a.axis}: {speed}; {acc}; travel {a.minimum:g} .. {a.maximum:g} {u}")
    if dx.peak_feed_mm_min is not None:
        levels = ", ".join(f"{p['level_mm_min']:g} ({p['seconds']:.2f} s)" for p in dx.plateaus[:5]) or "none"
        out.append(f"  feed ({dx.feed_source}): peak {dx.peak_feed_mm_min:,.1f} mm/min; plateaus {levels} mm/min; "
                   f"standstill {dx.standstill_s:.2f} s of {dx.motion_s:.2f} s in motion")
    if dx.lines:
        longest = ", ".join(f"{x['line']} ({x['seconds']:.2f} s)" for x in dx.lines["longest"][:3])
        out.append(f"  line stream: {dx.lines['distinct']} lines ({dx.lines['first']} .. {dx.lines['last']}), "
                   f"{dx.lines['changes']} changes; longest held: {longest}")
    fitted = dx.profile_values()
    out.append("  the data constrains: " + (", ".join(f"{k} = {v:g}" for k, v in fitted.items()) or "no limit")
               + ("" if profile_text(dx) is not None or not fitted else
                  " (no profile.toml: feedlog's generic profile is a 3-axis XYZ one)"))
    out += [f"  note: {n}" for n in dx.notes] + [f"  warning: {w}" for w in dx.warnings]
    out.append("  a program would add: " + "; ".join(dx.would_add[:3]) + " (--program PROGRAM)")
    return out


def to_json(dx: DataOnly) -> dict[str, Any]:
    def held(h) -> dict[str, Any] | None:
        return None if h is None else {"value": round(h.value, 4), "count": h.count, "seconds": h.seconds,
                                       "alone": h.alone}

    return {"mode": "no_program", "recordings": dx.recordings, "duration_s": dx.duration_s, "period_s": dx.period_s,
            "axes": {a.axis: {"unit": a.unit, "min": a.minimum, "max": a.maximum, "range": round(a.range, 6),
                              "peak_speed": a.peak_speed, "held_speed": held(a.held_speed),
                              "peak_acc": a.peak_acc, "held_acc": held(a.held_acc), "speed_from": a.speed_from,
                              "acc_limit": a.acc_limit} for a in dx.axes.values()},
            "feed": {"source": dx.feed_source, "peak_mm_min": dx.peak_feed_mm_min, "plateaus": dx.plateaus,
                     "motion_s": dx.motion_s, "standstill_s": dx.standstill_s},
            "lines": dx.lines, "profile": dx.profile_values(), "notes": dx.notes, "warnings": dx.warnings,
            "would_add": list(dx.would_add)}


def profile_text(dx: DataOnly) -> str | None:
    """The generic 3-axis profile with what the data constrains (None: not a 3-axis XYZ recording)."""
    from feedlog.diagnose.keys import with_values
    from feedlog.profile import load_profile

    if not dx.axes or set(dx.axes) - {"x", "y", "z"} or not dx.profile_values():
        return None
    base = load_profile(BASE_PROFILE)
    values: dict[str, float] = dict(dx.profile_values())
    raised = []
    for a in dx.axes.values():   # a generic value below what the machine did is raised to it (a lower bound)
        limits = base.axes.get(a.axis)
        if limits is None:
            continue
        for key, seen in (("vel_max", a.peak_speed), ("acc_max", a.peak_acc)):
            dotted = f"axes.{a.axis}.{key}"
            if dotted not in values and seen is not None and seen > getattr(limits, key):
                values[dotted] = round(seen, 3)
                raised.append(dotted)
        if a.minimum < limits.min_limit:
            values[f"axes.{a.axis}.min_limit"] = a.minimum
        if a.maximum > limits.max_limit:
            values[f"axes.{a.axis}.max_limit"] = a.maximum
    profile = with_values(base, values, name="fitted-from-data")
    fitted = dx.profile_values()
    head = [f"# fitted-from-data: {BASE_PROFILE} with what the recordings alone constrain "
            f"({', '.join(Path(r).name for r in dx.recordings)}), by feedlog diagnose without a program",
            *[f"#   {k} = {v:g}: held by the data" for k, v in fitted.items()],
            *[f"#   {k} raised to what the machine did (a lower bound)" for k in raised],
            f"#   everything else is {BASE_PROFILE}'s guess; diagnose with the program to fit the rest"]
    return "\n".join(head) + "\n" + profile.to_toml()


def report_md(dx: DataOnly) -> str:
    lines = ["# feedlog diagnose: without a program", "", *[f"    {s}" for s in summary_lines(dx)], "",
             "## Per axis", "", "| axis | travel | peak speed | held speed | peak acceleration | held acceleration | "
             "constrains |", "|---|---|---|---|---|---|---|"]
    for a in dx.axes.values():
        u = a.unit
        hs = "-" if a.held_speed is None else f"{a.held_speed.value:.3f} {u}/s ({a.held_speed.count}x)"
        ha = "-" if a.held_acc is None else f"{a.held_acc.value:.1f} {u}/s^2 ({a.held_acc.count}x)"
        limits = "acc_max" if a.acc_limit else "-"
        lines.append(f"| {a.axis} | {a.minimum:g} .. {a.maximum:g} {u} | {_num(a.peak_speed, 3)} {u}/s | {hs} | "
                     f"{_num(a.peak_acc)} | {ha} | {limits} |")
    lines += ["", "An acceleration is a limit where the axis held its top acceleration accelerating alone: a "
              "controller accelerates at its limit, though a planner may use a share of it (LinuxCNC uses "
              "half on moves it may blend). A speed is never claimed: a speed plateau is the programmed F or "
              "a limit, and only the program tells which. Everything else is a lower bound: the machine can "
              "do at least this.",
              "", "## Feed plateaus", "", "| feed (mm/min) | time (s) | plateaus |", "|---|---|---|"]
    lines += [f"| {p['level_mm_min']:g} | {p['seconds']:.3f} | {p['count']} |" for p in dx.plateaus]
    lines += ["", "## What a program would add", ""] + [f"- {w}" for w in dx.would_add] + [""]
    return "\n".join(lines)


def write_outputs(dx: DataOnly, out: Path) -> list[str]:
    from feedlog import storage

    written = ["report.md", "diagnose.json"]
    profile = profile_text(dx)
    with storage.publish_dir(str(out)) as folder:
        (folder / "report.md").write_text(report_md(dx))
        (folder / "diagnose.json").write_text(json.dumps(to_json(dx), indent=1, allow_nan=False) + "\n")
        if profile is not None:
            (folder / "profile.toml").write_text(profile)
            written.append("profile.toml")
    return written


def run(args: argparse.Namespace) -> int:
    """The `feedlog diagnose` command on recordings without a program (`applies(args)`)."""
    from feedlog.diagnose.cli import answer, refuse_taken_output

    try:
        refuse_taken_output(args)
        if args.profile is not None:
            print("feedlog diagnose: note: --profile is not used without a program (nothing is simulated)",
                  file=sys.stderr)
        dx = measure(read_all(args.recordings))
        written = write_outputs(dx, args.out) if args.out is not None else []
    except FeedlogError as exc:
        print(f"feedlog diagnose: error: {exc}", file=sys.stderr)
        return exc.exit_code
    return answer(args, to_json(dx), summary_lines(dx) + ([f"wrote {args.out}/: {', '.join(written)}"]
                                                          if written else []))
