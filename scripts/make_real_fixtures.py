#!/usr/bin/env python3
"""Write tests/fixtures/ingest/real/: small synthetic recordings shaped like public data of real machines.

We may not redistribute (or download) the public sets, so these are written by us, shaped like them:
a part program in the controller's dialect, run by feedlog.sim on a machine that is NOT the shipped
generic profile (so `feedlog diagnose` has something to find), then logged the way each source logs:

- `hurco_shdr.txt` + `hurco_part.nc`: an MTConnect adapter's SHDR log of a Hurco-like machine (Fanuc
  dialect: G0G80, G91G28Z0, G4 P ms), 10 Hz polls with jitter, values only when they change, inches
  and in/min (the adapter's native units), machine coordinates (a work offset G54 set on the machine),
  `line` = the executing program line, an UNAVAILABLE stretch while the adapter connects, a condition
  and a message line, adapter commands (the shape of the NIST smart-manufacturing test bed's logs).
- `mazak_streams.xml` + `mazak_part.nc`: MTConnect Streams XML of a Mazak-like machine, several
  saved `/sample` responses in one file (overlapping sequences), standard units (mm, PathFeedrate in
  mm/s), `LineLabel` = the N word of the executing block, and only part of the program (the finishing
  pass of a two-pass program, as a per-tool log would hold).
- `umich_experiment.csv` + `umich_part.nc`: the University of Michigan CNC mill tool-wear columns
  (X1_ActualPosition ... M1_sequence_number, M1_CURRENT_FEEDRATE in mm/s, Machining_Process), 10 Hz, no
  time column. Unlike the public files (a counter there, which the preset keeps apart), M1_sequence_number
  holds the N words of the executing blocks here: tests map it with `block_number=M1_sequence_number`.
- `sinumerik_trace.csv` + `sinumerik_part.mpf`: a Sinumerik 840D trace at 50 Hz (`;`-separated, BTSS
  variable names), with its .mpf program (G710, CYCLE832, `;` comments).

    .venv/bin/python scripts/make_real_fixtures.py      # rewrites the folder (deterministic)
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "tests" / "fixtures" / "ingest" / "real"
MM_PER_INCH = 25.4

HURCO = """%
O2101 (HURCO VM10 - POCKET, INCH)
N10 G0G17G20G40G49G80G90
N20 G91G28Z0.
N30 T1M6
N40 G90G54
N50 S8000M3
N60 G0X0.2Y0.2
N70 G43H1Z0.2
N80 G1Z-0.05F20.
N90 G64 P0.002
N100 X1.8F60.
N110 Y0.6
N120 X0.2
N130 Y1.0
N140 X1.8
N150 Y1.4
N160 X0.2
N170 Y1.8
N180 X1.8
N190 G4 P300
N200 G0Z0.2
N210 X1.0Y1.0
N220 G1Z-0.08F20.
N230 G2X1.5Y1.0I0.25J0.F40.
N240 G2X1.0Y1.0I-0.25J0.
N250 G0Z0.2
N260 G91G28Z0.
N270 M30
%
"""

MAZAK = """(MAZAK VCN - TWO PASSES, MM)
N10 G21 G90 G17 G94 G40 G49
N20 G54 G0 X5 Y5 Z10
N30 G1 Z-1 F300
N40 G64 P0.02
N50 X95 F1500
N60 Y45
N70 X5
N80 Y5
N90 G0 Z10
N100 (FINISH PASS)
N110 X0 Y0
N120 G1 Z-2 F300
N130 X100 F2400
N140 Y50
N150 X60
N160 G3 X40 Y50 R10
N170 G1 X0
N180 Y0
N190 G0 Z10
N200 M30
"""

UMICH = """(UMICH WAX S-SHAPE - ONE LAYER)
N10 G21 G90 G17 G94
N20 G0 X140 Y60 Z5
N30 G1 Z-1 F100
N40 G64 P0.05
N50 X150 Y70 F600
N60 X160 Y70
N70 G2 X170 Y80 R10
N80 G1 Y90
N90 G3 X160 Y100 R10
N100 G1 X150
N110 G2 X140 Y110 R10
N120 G1 Y120
N130 X165
N140 G0 Z5
N150 M30
"""

SINUMERIK = """%_N_PLATE_MPF
;$PATH=/_N_WKS_DIR/_N_PLATE_WPD
; plate contour, metric
N10 G710 G90 G17 G500 G54
N20 T="CUTTER 10" D1
N30 M6
N40 CYCLE832(0.01,_FINISH,1)
N50 S6000 M3
N60 G0 X0 Y0 Z5
N70 G642 G1 Z-1 F500
N80 X=80 F2000
N90 Y40 SOFT
N100 G2 X60 Y60 CR=20
N110 G1 X0
N120 MSG("contour done")
N130 Y0
N140 G0 Z5
N150 M30
"""


UMICH_FAST = """(UMICH WAX S-SHAPE - ONE LAYER, FAST, APPROACH AXIS BY AXIS)
N10 G21 G90 G17 G94
N20 G0 X140
N30 G0 Y60 Z5
N40 G1 Z-1 F300
N50 G64 P0.05
N60 X150 Y70 F1800
N70 X160 Y70
N80 G2 X170 Y80 R10
N90 G1 Y90
N100 G3 X160 Y100 R10
N110 G1 X150
N120 G2 X140 Y110 R10
N130 G1 Y120
N140 X165
N150 G0 Z5
N160 G0 X0 Y0
N170 M30
"""

UMICH_FACING = """(UMICH WAX FACING - ZIG-ZAG)
N10 G21 G90 G17 G94
N20 G0 X10 Y10 Z5
N30 G1 Z-0.5 F300
N40 G64 P0.05
N50 X110 F4800
N60 Y20
N70 X10
N80 Y30
N90 X110
N100 Y40
N110 X10
N120 Y50
N130 X110
N140 G0 Z5
N150 G0 X10 Y10
N160 M30
"""


def machine(name: str, *, vel: float, acc: float, rapid: float, tol: float = 0.01):
    """The machine each log is made on: generic-xyz with other limits (what diagnose should find)."""
    from feedlog.profile import load_profile

    base = load_profile("generic-xyz").to_dict()
    for axis in base["axes"].values():
        axis["vel_max"], axis["acc_max"] = vel, acc
    base["rapid_mm_min"] = rapid
    base["name"] = name
    base["interpolator"]["path_tolerance_mm"] = tol
    from feedlog.profile import MachineProfile
    return MachineProfile.from_dict(base)


def run(text: str, name: str, prof) -> tuple[pd.DataFrame, object]:
    from feedlog.sim import simulate
    from feedlog.toolpath import load_program

    program = load_program(text, name=name)
    sim = simulate(program, prof)
    return sim.series, program


def at(series: pd.DataFrame, t_s: np.ndarray) -> pd.DataFrame:
    """The simulated series at times t_s (s from its start): positions interpolated, line held."""
    ts = (series["t_ns"].to_numpy() - series["t_ns"].iloc[0]) / 1e9
    out = {"t_s": t_s}
    for c in ("x_mm", "y_mm", "z_mm", "feed_mm_min"):
        out[c] = np.interp(t_s, ts, series[c].to_numpy())
    idx = np.clip(np.searchsorted(ts, t_s, side="right") - 1, 0, len(ts) - 1)
    out["line"] = series["line"].to_numpy()[idx]
    out["block"] = series["block"].to_numpy()[idx]
    return pd.DataFrame(out)


def write_pair(log_name: str, log_lines: list[str], program_name: str, program: str) -> None:
    (OUT / log_name).write_text("\n".join(log_lines) + "\n")
    (OUT / program_name).write_text(program)


def hurco(rng: random.Random) -> None:
    prof = machine("hurco-like", vel=200.0, acc=1200.0, rapid=12000.0, tol=0.05)
    series, program = run(HURCO, "hurco_part.nc", prof)
    duration = (series["t_ns"].iloc[-1] - series["t_ns"].iloc[0]) / 1e9
    polls = np.arange(-1.0, duration + 1.0, 0.1)
    polls = polls + np.array([rng.uniform(-0.004, 0.004) for _ in polls])    # the adapter's 10 Hz polls
    s = at(series, np.clip(polls, 0.0, duration))
    offset_in = (-12.5, -8.25, -14.0)   # G54 set on the machine: machine = program + offset
    t0 = pd.Timestamp("2018-06-05T14:03:11.250Z").value

    def stamp(sec: float) -> str:
        return pd.Timestamp(t0 + int(round(sec * 1e9)), tz="UTC").strftime("%Y-%m-%dT%H:%M:%S.%fZ")

    lines = ["* shdrVersion: 2.0", "* adapterVersion: 1.4", "* device: Hurco01",
             f"{stamp(-1.6)}|avail|AVAILABLE|execution|UNAVAILABLE|Xact|UNAVAILABLE|Yact|UNAVAILABLE|"
             "Zact|UNAVAILABLE|path_feedrate|UNAVAILABLE|line|UNAVAILABLE",
             f"{stamp(-1.55)}|system|NORMAL||||",
             f"{stamp(-1.5)}|message|PRG01|Program O2101 loaded"]
    last: dict[str, str] = {}
    for k, (poll, row) in enumerate(zip(polls, s.itertuples())):
        values = {"Xact": f"{row.x_mm / MM_PER_INCH + offset_in[0]:.4f}",
                  "Yact": f"{row.y_mm / MM_PER_INCH + offset_in[1]:.4f}",
                  "Zact": f"{row.z_mm / MM_PER_INCH + offset_in[2]:.4f}",
                  "path_feedrate": f"{row.feed_mm_min / MM_PER_INCH:.2f}",
                  "line": str(int(row.line)),
                  "execution": "ACTIVE" if 0 < poll < duration else "READY",
                  "Sspeed": "8000" if poll > 0 else "0"}
        changed = [f"{key}|{v}" for key, v in values.items() if last.get(key) != v]
        last.update(values)
        if changed:
            lines.append(f"{stamp(poll)}|" + "|".join(changed))
        if k == 40:
            lines.append(f"{stamp(poll + 0.01)}|htemp|WARNING|HTEMP-1|HTEMP|1|HIGH|Oil temperature high")
    write_pair("hurco_shdr.txt", lines, "hurco_part.nc", HURCO)


def mazak(rng: random.Random) -> None:
    prof = machine("mazak-like", vel=300.0, acc=2500.0, rapid=20000.0)
    series, program = run(MAZAK, "mazak_part.nc", prof)
    n_word = program.blocks.set_index("line")["n_word"]
    # only the finishing pass: from the rapid to X0 Y0 (N110) to the end
    first_line = int(program.blocks.loc[program.blocks["n_word"] == 110, "line"].iloc[0])
    t_all = (series["t_ns"].to_numpy() - series["t_ns"].iloc[0]) / 1e9
    t_begin = float(t_all[np.argmax(series["line"].to_numpy() >= first_line)])
    duration = float(t_all[-1])
    t = np.arange(t_begin - 0.3, duration + 0.5, 0.05) + np.array([rng.uniform(0, 0.002) for _ in
                                                                   np.arange(t_begin - 0.3, duration + 0.5, 0.05)])
    t = np.clip(t, 0, duration)
    s = at(series, t)
    t0 = pd.Timestamp("2019-02-11T09:30:00Z").value
    items = []   # (sec, component, name, element, id, subtype, value)
    last: dict[str, str] = {}
    for _, row in s.iterrows():
        vals = {"Xabs": ("Linear", "X", "Position", "ACTUAL", f"{row.x_mm:.4f}"),
                "Yabs": ("Linear", "Y", "Position", "ACTUAL", f"{row.y_mm:.4f}"),
                "Zabs": ("Linear", "Z", "Position", "ACTUAL", f"{row.z_mm:.4f}"),
                "Frt": ("Path", "path", "PathFeedrate", "ACTUAL", f"{row.feed_mm_min / 60.0:.3f}"),
                "label": ("Path", "path", "LineLabel", "", str(int(n_word.get(int(row.line), -1))))}
        for key, (comp, cname, el, sub, v) in vals.items():
            if key == "label" and v == "-1":
                continue
            if last.get(key) != v:
                items.append((float(row.t_s), comp, cname, el, key, sub, v))
                last[key] = v
    items.insert(3, (float(s.t_s.iloc[0]), "Path", "path", "PathFeedrate", "Frt", "ACTUAL", "UNAVAILABLE"))
    docs, seq = [], 1000
    chunk = max(1, len(items) // 3)
    for d in range(3):  # three saved /sample responses, the next repeating the last items of the one before
        lo = max(0, d * chunk - 5)
        hi = len(items) if d == 2 else (d + 1) * chunk
        body = {"Linear": {}, "Path": {}}
        for i in range(lo, hi):
            sec, comp, cname, el, key, sub, v = items[i]
            stamp = pd.Timestamp(t0 + int(round(sec * 1e9)), tz="UTC").strftime("%Y-%m-%dT%H:%M:%S.%fZ")
            category = "Events" if el == "LineLabel" else "Samples"
            attrs = f'dataItemId="{key}" timestamp="{stamp}" name="{key}" sequence="{seq + i}"'
            if sub:
                attrs += f' subType="{sub}"'
            body[comp].setdefault(cname, {}).setdefault(category, []).append(f"<{el} {attrs}>{v}</{el}>")
        parts = ['<?xml version="1.0" encoding="UTF-8"?>',
                 '<MTConnectStreams xmlns="urn:mtconnect.org:MTConnectStreams:1.3" '
                 'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">',
                 f'  <Header creationTime="2019-02-11T09:31:{d:02d}Z" sender="agent" instanceId="1549877000" '
                 f'version="1.3.0" bufferSize="131072" nextSequence="{seq + hi}" firstSequence="1" '
                 f'lastSequence="{seq + hi - 1}"/>',
                 "  <Streams>", '    <DeviceStream name="Mazak01" uuid="mazak-vcn-01">']
        for comp, named in body.items():
            for cname, cats in named.items():
                parts.append(f'      <ComponentStream component="{comp}" name="{cname}" componentId="{cname.lower()}1">')
                for category, elements in cats.items():
                    parts.append(f"        <{category}>")
                    parts += [f"          {e}" for e in elements]
                    parts.append(f"        </{category}>")
                parts.append("      </ComponentStream>")
        parts += ["    </DeviceStream>", "  </Streams>", "</MTConnectStreams>"]
        docs.append("\n".join(parts))
    write_pair("mazak_streams.xml", docs, "mazak_part.nc", MAZAK)


def umich(rng: random.Random) -> None:
    """The UMich set holds many experiments of one machine; three here, on programs that tell its limits apart."""
    prof = machine("umich-mill", vel=150.0, acc=800.0, rapid=6000.0)
    umich_experiment(rng, prof, UMICH, "umich_part.nc", "umich_experiment.csv")
    for k, text in ((2, UMICH_FAST), (3, UMICH_FACING)):
        umich_experiment(random.Random(f"fixtures:umich:{k}"), prof, text, f"umich_part_{k:02d}.nc",
                         f"umich_experiment_{k:02d}.csv")


def umich_experiment(rng: random.Random, prof, text: str, program_name: str, csv_name: str) -> None:
    series, program = run(text, program_name, prof)
    n_word = program.blocks.set_index("line")["n_word"]
    duration = (series["t_ns"].iloc[-1] - series["t_ns"].iloc[0]) / 1e9
    t = np.arange(-0.8, duration + 0.8, 0.1)
    s = at(series, np.clip(t, 0, duration))
    v = np.gradient(s[["x_mm", "y_mm", "z_mm"]].to_numpy(), 0.1, axis=0)
    rows = []
    for i, row in s.iterrows():
        rec = {}
        for j, axis in enumerate("XYZ"):
            pos = float(row[f"{axis.lower()}_mm"])
            rec[f"{axis}1_ActualPosition"] = round(pos + rng.gauss(0, 0.002), 4)
            rec[f"{axis}1_ActualVelocity"] = round(float(v[i, j]), 3)
            rec[f"{axis}1_ActualAcceleration"] = 0.0
            rec[f"{axis}1_CommandPosition"] = round(pos, 4)
            rec[f"{axis}1_CurrentFeedback"] = round(rng.gauss(0, 0.5), 3)
            rec[f"{axis}1_OutputPower"] = round(abs(rng.gauss(0, 1e-3)), 6)
        rec["S1_ActualVelocity"] = 0.0 if row.t_s <= 0 else 20.0
        rec["M1_CURRENT_PROGRAM_NUMBER"] = 1
        rec["M1_sequence_number"] = int(n_word.get(int(row.line), 0))
        rec["M1_CURRENT_FEEDRATE"] = round(float(row.feed_mm_min) / 60.0, 3)   # mm/s, as the public files
        rec["Machining_Process"] = "Prep" if row.t_s <= 0 else ("Layer 1 Up" if row.t_s < duration else "End")
        rows.append(rec)
    pd.DataFrame(rows).to_csv(OUT / csv_name, index=False)
    (OUT / program_name).write_text(text)


def sinumerik(rng: random.Random) -> None:
    prof = machine("sinumerik-like", vel=250.0, acc=1500.0, rapid=15000.0)
    series, program = run(SINUMERIK, "sinumerik_part.mpf", prof)
    duration = (series["t_ns"].iloc[-1] - series["t_ns"].iloc[0]) / 1e9
    t = np.arange(-0.4, duration + 0.4, 0.02)
    s = at(series, np.clip(t, 0, duration))
    frame = pd.DataFrame({
        "Time": np.round(t - t[0], 3),
        "/Channel/GeometricAxis/actToolBasePos[u1,1]": s.x_mm.round(4),
        "/Channel/GeometricAxis/actToolBasePos[u1,2]": s.y_mm.round(4),
        "/Channel/GeometricAxis/actToolBasePos[u1,3]": s.z_mm.round(4),
        "/Channel/State/actFeedRateIpo[u1]": s.feed_mm_min.round(2),
        "/Channel/ProgramInfo/actLineNumber[u1]": s.line.astype(int),
        "/Channel/Spindle/actSpeed[u1]": np.where(t > 0, 6000.0, 0.0),
    })
    with open(OUT / "sinumerik_trace.csv", "w", newline="") as f:
        f.write("; SINUMERIK 840D sl trace, 50 Hz, channel 1\n")
        frame.to_csv(f, sep=";", index=False)
    (OUT / "sinumerik_part.mpf").write_text(SINUMERIK)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for fn in (hurco, mazak, umich, sinumerik):
        fn(random.Random(f"fixtures:{fn.__name__}"))
    for p in sorted(OUT.iterdir()):
        print(f"{p.relative_to(ROOT)}: {p.stat().st_size} bytes")


if __name__ == "__main__":
    main()
