#!/usr/bin/env python3
"""Record recordings/mystery/: three programs on a LinuxCNC machine that differs from the shipped
reference machine (recordings/configs/xyz.ini) in one undisclosed way.

The recordings carry the shipped profile (`linuxcnc-xyz`), as a user who does not know about the
change would have it, and not the machine's INI (which would give the change away). `feedlog demo`
diagnoses them in its "mystery machine" section; tests/linuxcnc/test_mystery.py checks that
`feedlog diagnose` finds the change. LinuxCNC runs in real time: about 40 s.

    .venv/bin/python scripts/make_mystery.py [--force]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import tomli_w

sys.path.insert(0, str(Path(__file__).resolve().parent))
from linuxcnc_variants import derive_machine

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "recordings" / "mystery"
PROGRAMS = ("corners_f2000_p005", "pocket_f3000_p001", "mix_001")
# the undisclosed change (what `feedlog diagnose` is to find)
CHANGES = [("AXIS_Y", "MAX_ACCELERATION", 350), ("JOINT_1", "MAX_ACCELERATION", 350)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--force", action="store_true", help="record again over existing files")
    args = ap.parse_args()
    from feedlog.ingest import read_recording, write_recording
    from feedlog.ingest.linuxcnc import record_linuxcnc
    from feedlog.ingest.linuxcnc_session import isolation_available

    OUT.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ini = derive_machine("xyz", Path(tmp) / "machine", changes=CHANGES, name="mystery")
        for name in PROGRAMS:
            out = OUT / f"mystery_{name}.mcap"
            if out.exists() and not args.force:
                print(f"{out.name}: exists (--force to record again)")
                continue
            raw = Path(tmp) / f"{name}.mcap"
            summary = record_linuxcnc(ini, ROOT / "recordings" / "programs" / f"{name}.ngc", raw,
                                      profile="linuxcnc-xyz", isolate=isolation_available() is None,
                                      streams="compact", timeout_s=120)
            rec = read_recording(raw)
            rec.attachments = {k: v for k, v in rec.attachments.items() if k != "machine.ini" and
                               not k.startswith("hal/")}
            rec.metadata["ini"] = "mystery.ini"
            rec.metadata["notes"] = "a LinuxCNC machine that is not quite the shipped linuxcnc-xyz"
            write_recording(out, rec, overwrite=True, compression="zstd", level=19)
            rows.append({"name": out.stem, "file": out.name, "program": f"../programs/{name}.ngc",
                         "cycle_time_s": round(float(summary["cycle_time_s"]), 6)})
            print(f"{out.name}: {summary['cycle_time_s']:.3f} s")
    if rows:
        (OUT / "mystery.toml").write_text(
            "# recordings of one LinuxCNC machine that differs from linuxcnc-xyz in one undisclosed way\n"
            "# (scripts/make_mystery.py); `feedlog diagnose recordings/mystery/*.mcap` finds it\n"
            + tomli_w.dumps({"profile": "linuxcnc-xyz", "recording": rows}))


if __name__ == "__main__":
    main()
