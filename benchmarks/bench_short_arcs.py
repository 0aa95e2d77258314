"""Short arcs against LinuxCNC: the interpreter recordings (recordings/interp/) simulated with LinuxCNC's
short-arc rules (docs/sim.md, "Short arcs") and blend rules ("Blend geometry", "Blend choice",
"Unfinalized last move") switched on one after the other, the time per program line before and after the
blend rules, and per block on the exact-stop spline run (align's block times against the simulated ones).

    .venv/bin/python benchmarks/bench_short_arcs.py [MORE.mcap ...]

MORE: other recordings of programs that need no tool table (e.g. the G64 P0.01 F1200 spline run that
tests/linuxcnc/test_linuxcnc_interp_live.py records).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.align import align_recording
from feedlog.ingest import read_recording
from feedlog.ingest.recording import PROFILE_ATTACHMENT
from feedlog.ingest.subroutine_files import load_recorded_program
from feedlog.profile import MachineProfile
from feedlog.sim import simulate

ROOT = Path(__file__).resolve().parents[1]
def _rules(share: bool, as_lines: bool, curved: bool, sync: bool = False, blends: bool = False) -> dict:
    return {"lookahead": {"arc_share_from_speed": share, "finalize_on_next": blends},
            "naive_cam": {"arcs_as_lines": as_lines},
            "blend_arc": {"curved_blend_speed": curved, "sync_stop": sync, "arc_side_lengths": sync,
                          "curved_blend_geometry": blends, "parabolic_choice": blends, "open_end_entry": blends}}


def _line_error_ms(rec, blocks) -> float:
    """Mean |simulated - measured| seconds per program line (LinuxCNC's line stream), in ms."""
    line = rec.streams["line"]
    t, ln = line["t_ns"].to_numpy() / 1e9, line["line"].to_numpy()
    starts = np.flatnonzero(np.r_[True, ln[1:] != ln[:-1]])
    measured = pd.Series(np.diff(np.r_[t[starts], t[-1]]), index=ln[starts]).groupby(level=0).sum()
    sim = pd.Series(blocks["duration_s"].to_numpy(), index=blocks["line"].to_numpy()).groupby(level=0).sum()
    both = sim.index.intersection(measured.index)
    return float(np.abs(sim[both] - measured[both]).mean() * 1e3)


# cumulative: none of the rules, then the share, then the split, then the curved corners, then the stop
# before words run at rest with the arc-side blend lengths (all: the LinuxCNC profiles' setting; a
# recording's attached profile may predate them, so they are set here)
STEPS = [("none", _rules(False, False, False)), ("+share", _rules(True, False, False)),
         ("+as lines", _rules(True, True, False)), ("+curved", _rules(True, True, True)),
         ("+sync+sides", _rules(True, True, True, True)), ("+blends", _rules(True, True, True, True, True))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("more", nargs="*", type=Path)
    args = ap.parse_args()
    paths = [p for p in sorted((ROOT / "recordings" / "interp").glob("*.mcap")) if p.stem != "cutter_comp"]
    print(f"{'recording':22s} {'measured':>9s} " + " ".join(f"{name:>10s}" for name, _ in STEPS)
          + "  per line ms (+sync+sides -> +blends)")
    for path in paths + list(args.more):
        rec = read_recording(path)
        profile = MachineProfile.from_toml(rec.attachments[PROFILE_ATTACHMENT].decode(), source=PROFILE_ATTACHMENT)
        program = load_recorded_program(rec, name=f"{path.stem}:program.ngc")
        measured = float(rec.metadata["cycle_time_s"])
        runs = [simulate(program, profile, mechanisms=m) for _, m in STEPS]
        errs = [100 * (r.cycle_time_s / measured - 1) for r in runs]
        lines = [_line_error_ms(rec, r.blocks) for r in runs[-2:]]
        print(f"{path.stem:22s} {measured:9.3f} " + " ".join(f"{e:+9.2f}%" for e in errs)
              + f"  {lines[0]:.2f} -> {lines[1]:.2f}")
        if path.stem == "splines_g611_f1200":
            got = align_recording(rec).blocks.set_index("block")["duration_s"]
            for name, mech in (STEPS[0], STEPS[-1]):
                sim = simulate(program, profile, mechanisms=mech).blocks.set_index("block")["duration_s"]
                both = got.index.intersection(sim.index)
                diff = (sim[both] - got[both]).to_numpy() * 1e3
                print(f"  per block ({name}): {len(both)} blocks, mean {diff.mean():+.2f} ms, "
                      f"max |diff| {np.abs(diff).max():.2f} ms")


if __name__ == "__main__":
    main()
