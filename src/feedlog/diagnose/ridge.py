"""Two limits of one axis the recordings cannot tell apart: the profile likelihood along their ridge.

A calibration scans each limit with the others held (`calibrate._interval`). Where an axis only makes
moves whose time depends on its velocity and its acceleration limit together (a five-axis program's Z:
short moves coupled to the rotaries), that scan is narrow for both, yet a higher velocity with a lower
acceleration fits as well: on generic-xyzac with a machine at Z 40 mm/s and 350 mm/s^2, three mix5ax
recordings give the same loss, within the servo cycle's steps, from 34 mm/s with 449 mm/s^2 to 47.6 with
314 (`benchmarks/bench_calibrate_five.py`). The Gauss-Newton covariance sees it only as a singular
matrix. Here the velocity limit is moved outwards step by step with the acceleration limit refitted at
each step (`joint.joint_fit` on the one parameter); while the refitted loss stays within the threshold
the two are on a ridge. A ridge at least `MIN_SPAN` wide in velocity, along which the refitted
acceleration leaves its own interval, makes the two a *pair*: each is reported as not constrained on its
own, with the ridge's ends, and the calibration air-cut that tells the ends apart
(`separate.separating_program`) is named. Where the acceleration stays put (Y on the same recordings:
35 to 106 mm/s with 449.8 to 449.7 mm/s^2) the velocity alone is free: a speed never held, whose scan
with the others held had closed on a servo cycle's step; it is reported as bounded from below only.

The threshold is the profile likelihood's (`n log(L / L*) <= CHI2`), at least `STEP_TOLERANCE` above the
best loss: a simulation that moves in whole servo cycles makes the loss of neighbouring values step by a
few percent (6.24e-5 to 6.68e-5 along the ridge above), which is no evidence against either value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from feedlog.diagnose.fit import Scorer
from feedlog.diagnose.hypothesis import Hypothesis
from feedlog.diagnose.joint import joint_fit, loss

CHI2 = 3.84                      # 95 % for one parameter (as calibrate)
STEP_TOLERANCE = 1.1             # the refitted loss may be this many times the best and stay on the ridge
FACTORS = (1.05, 1.1, 1.15, 1.2, 1.3, 1.45, 1.7, 2.0, 3.0)   # velocity moved outwards by these factors
MIN_SPAN = 1.05                  # a ridge this wide (velocity high / low end) makes a pair


@dataclass
class Pair:
    """Two limits of one axis on a ridge: equally good from `low` to `high` (each {key: value})."""
    keys: tuple[str, str]                    # (velocity key, acceleration key)
    fitted: dict[str, float]
    low: dict[str, float]                    # the ridge's end at the lowest velocity still on it
    high: dict[str, float]
    open_ends: tuple[bool, bool]             # the scan reached the search bound on that side, still on the ridge
    trade_off: bool = True                   # the acceleration moves along it (False: the velocity alone is free)
    separated_by: dict[str, Any] | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"parameters": list(self.keys), "fitted": self.fitted, "low": self.low, "high": self.high,
                "open_ends": list(self.open_ends), "separated_by": self.separated_by}


def threshold(scorer: Scorer, best: float, n: float) -> float:
    base = max(best, float(scorer.floor.sum()), 1e-300)
    return max(base * np.exp(CHI2 / n), STEP_TOLERANCE * best)


def walk(scorer: Scorer, model: dict[str, Any], vel: Hypothesis, acc: Hypothesis,
         n: float) -> tuple[dict[str, float], dict[str, float], tuple[bool, bool]]:
    """The ridge's ends: the lowest and highest velocity (with its refitted acceleration) whose loss stays
    within the threshold, and whether a side ran into the search bounds still on it."""
    v0 = float(model[vel.key])
    limit = threshold(scorer, loss(scorer, model), n)
    ends, open_ends = [], []
    for sign in (-1, 1):
        last = {vel.key: v0, acc.key: float(model[acc.key])}
        opened = True
        for f in FACTORS:
            v = v0 * f ** sign
            if not vel.lower <= v <= vel.upper:
                break
            # from the last point on the ridge: the acceleration that goes with a velocity moves with it
            trial = joint_fit(scorer, {**model, **acc.values(last[acc.key]), **vel.values(v)}, [acc])
            if loss(scorer, trial) > limit:
                opened = False
                break
            last = {vel.key: v, acc.key: float(trial[acc.key])}
        ends.append(last)
        open_ends.append(opened)
    return ends[0], ends[1], (open_ends[0], open_ends[1])


def ridges(scorer: Scorer, model: dict[str, Any], hyps: Sequence[Hypothesis], n: float,
           scans: dict[str, tuple[float | None, float | None]]) -> list[Pair]:
    """The axes whose velocity limit (with the acceleration limit, both in `hyps`) moves along a ridge at
    least `MIN_SPAN` wide. `trade_off` when the refitted acceleration leaves its own interval (`scans`,
    the others held) on the way: then the two are a pair; otherwise the velocity alone is free there (a
    speed the recordings never held, whose held scan closed on a servo cycle's step)."""
    by_key = {h.key: h for h in hyps}
    out = []
    for h in hyps:
        if not h.key.endswith(".vel_max"):
            continue
        acc = by_key.get(h.key[: -len("vel_max")] + "acc_max")
        if acc is None:
            continue
        low, high, open_ends = walk(scorer, model, h, acc, n)
        if high[h.key] / low[h.key] < MIN_SPAN:
            continue
        lo_a, hi_a = scans[acc.key]
        moved = any(not (lo_a or 0.0) <= end[acc.key] <= (hi_a or np.inf) for end in (low, high))
        out.append(Pair(keys=(h.key, acc.key), fitted={h.key: float(model[h.key]), acc.key: float(model[acc.key])},
                        low=low, high=high, open_ends=open_ends, trade_off=moved))
    return out
