"""The demo's answer in plain sentences: what the diagnosis found, then a five-line summary of the
cycle-time table, for the top of `report.md` and the end of the console output.

Every percentage comes from `report.error_summary` and is printed by `diagnose.plain.pct`, so the
sentences, the summary list and the table's footer agree.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from feedlog.diagnose.plain import pct
from feedlog.viz.report import error_summary

SAME_AS_SIM = 1e-3   # hybrid within 0.1 % of the simulation: it learned (almost) no correction
TERMS = ("- *mean error*: the mean over recordings of |estimate - measured| / measured cycle time.",
         "- *held out*: recordings of the `test` split, which no model was trained on.",
         "- *CAM time*: every block at its programmed feed, no acceleration: what a CAM system estimates.")


def hybrid_equals_sim(table: pd.DataFrame) -> float:
    """Share of rows where the hybrid's cycle time is within `SAME_AS_SIM` of the simulation's (0 without both)."""
    if "hybrid_s" not in table or "sim_s" not in table:
        return 0.0
    sim, hyb = table["sim_s"].to_numpy(np.float64), table["hybrid_s"].to_numpy(np.float64)
    ok = np.isfinite(sim) & np.isfinite(hyb) & (sim > 0)
    return float(np.mean(np.abs(hyb[ok] / sim[ok] - 1) < SAME_AS_SIM)) if ok.any() else 0.0


def summary_sentences(table: pd.DataFrame, *, run_time_s: float | None = None,
                      models: Sequence[str] = ()) -> list[str]:
    """Five lines: how many recordings, how close the simulation is, the CAM time, the best learner,
    the run time."""
    measured = int(np.isfinite(table["measured_s"].to_numpy(np.float64)).sum()) if len(table) else 0
    test = int((table["split"] == "test").sum()) if "split" in table else 0
    overall, held = error_summary(table), error_summary(table, split="test")
    lines = [f"{len(table)} recordings, {measured} with a measured cycle time ({test} held out for testing)."]

    def both(name: str) -> str:
        return pct(overall[name]) + (f" (held out: {pct(held[name])})" if name in held else "")

    if "sim" in overall:
        lines.append(f"The simulation (feedlog's interpolator model with each recording's machine profile) misses "
                     f"the measured cycle time by {both('sim')} on average.")
    if "cam" in overall:
        lines.append(f"The CAM time misses it by {both('cam')}: that gap is what modelling the interpolator buys.")
    learned = [m for m in models if m in held] or [m for m in models if m in overall]
    if learned:
        scores = held if all(m in held for m in learned) else overall
        best = min(learned, key=lambda m: scores[m])
        where = "on held-out recordings" if scores is held else "over all recordings"
        text = f"Best learned model {where}: {best}, {pct(scores[best])} mean error (demo's quick preset)."
        alone = [m for m in learned if m != "hybrid"]
        if best == "hybrid" and alone:
            second = min(alone, key=lambda m: scores[m])
            text += f" Without the simulation underneath: {second}, {pct(scores[second])}."
        share = hybrid_equals_sim(table)
        if "hybrid" in learned and share >= 0.5:
            text += (f" The hybrid model multiplies the simulation by a learned correction; it learned almost "
                     f"none here, so it equals the simulation within 0.1 % on {pct(100 * share, 0)} of the "
                     "recordings (docs/train.md).")
        lines.append(text)
    if run_time_s is not None:
        lines.append(f"The demo ran for {run_time_s:.1f} s.")
    return lines
