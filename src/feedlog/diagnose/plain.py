"""A diagnosis in plain sentences, for the first lines of a report: what the machine did against the
simulation, the cause in the controller's own parameter names, how well the fix holds on data it was not
fitted on, and a glossary line for each term of art the tables below use.

`answer(dx)` -> sentences; `glossary(terms)` -> one line per term; `noise_floor_text(noise)` and
`timings_text(timings)` turn the diagnosis' dicts into a sentence each. Percentages are rounded once
here (`pct`), so a figure reads the same wherever these sentences are quoted.
"""

from __future__ import annotations

import math
from typing import Any

from feedlog.controller_names import label, with_names

GLOSSARY = {
    "held-out gain": "the share of the simulation's error on data left out of the fit (another recording, "
                     "or other stretches of one) that a change removes",
    "misplaced time": "the sum over motion segments of |simulated - measured| duration, as a share of the "
                      "measured time: time the simulation spends in the wrong place even when the totals agree",
    "noise floor": "how much error the recordings' own sampling and jitter explain; smaller effects are "
                   "not named as causes",
    "held out": "checked on recordings (or stretches) the fit did not see",
}


def pct(value: float | None, digits: int = 1) -> str:
    """A percentage as reports print it: `12.2 %`, never `-0.0 %`; `n/a` when missing."""
    if value is None or not math.isfinite(value):
        return "n/a"
    text = f"{abs(value):.{digits}f}"
    sign = "-" if value < 0 and float(text) != 0 else ""
    return f"{sign}{text} %"


def _number(value: Any, unit: str) -> str:
    if isinstance(value, bool) or value is None:
        return "on" if value else "off"
    if isinstance(value, (int, float)):
        if math.isinf(value):
            return "unlimited"
        return f"{value:.4g} {unit}".strip()
    return f"{value} {unit}".strip()


def direction(error_pct: float) -> str:
    """`error_pct` = (simulated - measured) / measured: in words, against the measured time."""
    if abs(error_pct) < 0.05:
        return "matches the measured time (within 0.05 %)"
    return f"is {pct(abs(error_pct))} {'short of' if error_pct < 0 else 'over'} the measured time"


def answer(dx) -> list[str]:
    """The diagnosis in a few sentences, answer first."""
    cyc = dx.levels["cycle"]
    n = len(dx.cases)
    before = cyc["error_before_pct"]
    took = "longer" if before < 0 else "less time"
    out = [f"The machine took {took} than simulated: {cyc['measured_s']:.1f} s measured, "
           f"{cyc['simulated_before_s']:.1f} s simulated with the profile `{dx.profile.name}` over {n} "
           f"recording{'s' if n != 1 else ''}; the simulation {direction(before)}."]
    controller = getattr(dx.profile, "controller", "") or ""
    for i, f in enumerate(dx.findings, 1):
        lead = "Cause" if len(dx.findings) == 1 else f"Cause {i}"
        key = with_names(f.parameter, controller)
        if f.kind == "mechanism":
            out.append(f"{lead}: {label(f.parameter)} is at work on this machine ({_number(f.fitted_value, f.unit)}); "
                       f"the profile leaves it off. Key: {key}.")
        else:
            profile = _number(f.profile_value, f.unit)
            out.append(f"{lead}: the {label(f.parameter)} is {_number(f.fitted_value, f.unit)} on this machine, "
                       f"not {profile} as the profile says. Key: {key}.")
        if f.evidence:
            out.append(f"The recordings show it without any simulation: {f.evidence}.")
    held = [r for r in (dx.held_out or {}).get("recordings", []) if r.get("error_after_pct") is not None]
    if dx.findings:
        after = cyc["error_after_pct"]
        text = f"With {'this change' if len(dx.findings) == 1 else 'these changes'} the simulation {direction(after)}"
        if held:
            worst = max(abs(r["error_after_pct"]) for r in held)
            text += (f"; fitted without each recording in turn, it is within {pct(worst, 2)} of that recording "
                     "(held out)")
        out.append(text + ".")
    else:
        out.append("No cause is named: no change the diagnosis knows removes a material, repeatable share of "
                   "the error on held-out data.")
    for u in dx.unexplained:
        out.append(f"Still unexplained ({u['level']}): {pct(u['error_pct'])} of the time is misplaced, "
                   f"{u['systematic_share_pct']:.0f} % of it systematic.")
    return out


def glossary(terms: list[str] | None = None) -> list[str]:
    """One line per term of art (all of them by default)."""
    return [f"- *{t}*: {GLOSSARY[t]}." for t in (terms or list(GLOSSARY))]


def noise_floor_text(noise: dict[str, Any]) -> str:
    """The noise floor as a sentence (was a raw dict)."""
    parts = []
    if noise.get("timing_pct") is not None:
        parts.append(f"segment timing {pct(noise['timing_pct'], 2)} of the time")
    if noise.get("line_s") is not None:
        parts.append(f"program-line timestamps {1e3 * noise['line_s']:.2f} ms")
    if noise.get("feedback_mm") is not None:
        parts.append(f"feedback positions {1e3 * noise['feedback_mm']:.2f} um")
    periods = [p for p in noise.get("sampling_period_s") or [] if p]
    if periods:
        parts.append("sampled every " + ", ".join(f"{1e3 * p:g} ms" for p in periods))
    limits = []
    if noise.get("min_effect_pct") is not None:
        limits.append(f"change the time by at least {pct(noise['min_effect_pct'])}")
    if noise.get("min_gain") is not None:
        limits.append(f"remove at least {100 * noise['min_gain']:.0f} % of the held-out error")
    if noise.get("min_effect_line_s") is not None:
        limits.append(f"move a program line by at least {1e3 * noise['min_effect_line_s']:.1f} ms")
    text = "Noise floor: " + ("; ".join(parts) if parts else "not measured") + "."
    if limits:
        text += " A cause is named only if it can " + ", ".join(limits[:-1]) + (" and " if len(limits) > 1 else "") \
                + limits[-1] + "."
    return text


def timings_text(timings: dict[str, float]) -> str:
    """The diagnosis' own run time per step, as a sentence."""
    steps = {k: float(v) for k, v in timings.items() if isinstance(v, (int, float)) and math.isfinite(v)}
    if not steps:
        return ""
    total = steps.pop("total", sum(steps.values()))
    return (f"Diagnosis run time {total:.1f} s ("
            + ", ".join(f"{k} {v:.2f} s" for k, v in steps.items()) + ").")
