"""LinuxCNC's interpreter as a reference: run it on a program (lcnc_canon.py under Debian's Python)
and compare its canonical motion with feedlog's interpreter, move by move."""

from __future__ import annotations

import json
import math
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SYSTEM_PYTHON = "/usr/bin/python3"
NCFILES = Path("/usr/share/linuxcnc/ncfiles")
TOOLS = HERE.parents[1] / "fixtures" / "interp" / "tools.tbl"


def available() -> str | None:
    """None when LinuxCNC's `gcode` module runs here, else why not."""
    if not Path(SYSTEM_PYTHON).exists():
        return "Debian's /usr/bin/python3 is missing"
    probe = subprocess.run([SYSTEM_PYTHON, "-c", "import gcode"], capture_output=True, text=True)
    if probe.returncode:
        return "LinuxCNC's gcode module is not installed (apt-get install linuxcnc-uspace)"
    return None


def _needs_linuxcnc():
    import os

    import pytest
    missing = available()
    return pytest.mark.skipif(missing is not None and os.environ.get("FEEDLOG_REQUIRE_LINUXCNC") != "1",
                              reason=missing or "")


def run_both(program: Path, **kw):
    """(LinuxCNC's Reference, feedlog's Program or None, feedlog's ProgramError or None) for one file."""
    from feedlog.errors import ProgramError
    from feedlog.toolpath.interp import interpret

    ref = reference(program)
    try:
        return ref, interpret(program, **kw), None
    except ProgramError as exc:
        return ref, None, exc


def check_refused_alike(ref: Reference, error, text: str) -> None:
    """Where LinuxCNC refuses a program feedlog refuses it, on LinuxCNC's line (or the one before: read
    errors) or, inside a subprogram of the same file, naming LinuxCNC's line (the call) in its stack."""
    assert error is not None, f"LinuxCNC: line {ref.line}: {ref.message}\n{text}"
    assert error.line in (ref.line, ref.line - 1) or f":{ref.line}" in str(error), \
        (error.line, ref.line, ref.message, str(error), text)


def subroutine_path() -> list[Path]:
    return [NCFILES, NCFILES / "ngcgui_lib", NCFILES / "ngcgui_lib" / "utilitysubs",
            NCFILES / "remap_lib" / "common_nc_subs", NCFILES / "gladevcp_lib"]


@dataclass
class Reference:
    moves: list[dict]
    error: bool
    line: int
    message: str
    precision: float = 0.0      # what LinuxCNC printed was rounded to (0: full double precision)


def reference(program: Path, *, tools: Path = TOOLS, var: Path | None = None, subs: list[Path] = (),
              cwd: Path | None = None) -> Reference:
    """LinuxCNC's canonical moves for `program`: from its `gcode` module in full precision (with the line
    of every move), or, where that module cannot run the program (it crashes on T words outside a
    running LinuxCNC), from the `rs274` command, which prints 4 decimals and no line numbers
    (`Reference.precision` says which)."""
    out = subprocess.run([SYSTEM_PYTHON, str(HERE / "lcnc_canon.py"), str(program), str(tools),
                          str(var or ""), ":".join(str(s) for s in subs)],
                         capture_output=True, text=True, timeout=120, cwd=cwd or program.parent)
    lines = [json.loads(s) for s in out.stdout.splitlines() if s.startswith("{")]
    if not lines or "result" not in lines[-1]:
        return _rs274(program, tools=tools, var=var, subs=subs, cwd=cwd)
    tail = lines.pop()
    return Reference(moves=[m for m in lines if m["kind"] != "dwell"], error=tail["error"], line=tail["line"],
                     message=tail["message"])


_CALL = re.compile(r"^\s*\d+ N[.\d]+\s+(\w+)\((.*)\)")
_PLANES = {"CANON_PLANE_XY": 1, "CANON_PLANE_YZ": 2, "CANON_PLANE_XZ": 3}


# rs274 takes its tool table and parameter file in inches (its external length unit); ours are mm
_VAR_LENGTHS = ({b + k for b in [5160, 5180] + [5200 + 20 * s for s in range(1, 10)] for k in (1, 2, 3, 7, 8, 9)}
                | {5211, 5212, 5213, 5217, 5218, 5219})


def _var_in_inches(var: Path) -> str:
    out = []
    for raw in var.read_text().splitlines():
        parts = raw.split()
        if len(parts) == 2:
            i, v = int(parts[0]), float(parts[1])
            out.append(f"{i}\t{v / 25.4 if i in _VAR_LENGTHS else v!r}")
    return "\n".join(out) + "\n"


def _tools_in_inches(tools: Path) -> str:
    out = []
    for raw in tools.read_text().splitlines():
        code = raw.split(";", 1)[0].split()
        if not code:
            continue
        words = []
        for token in code:
            letter, value = token[0].upper(), float(token[1:])
            words.append(f"{letter}{value / 25.4 if letter in 'XYZUVWD' else value:.10g}"
                         if letter not in "TP" else f"{letter}{int(value)}")
        out.append(" ".join(words))
    return "\n".join(out) + "\n"


def _rs274(program: Path, *, tools: Path, var: Path | None, subs, cwd) -> Reference:
    with tempfile.TemporaryDirectory() as tmp:
        ini = Path(tmp) / "ref.ini"
        var_copy = Path(tmp) / "ref.var"
        var_copy.write_text(_var_in_inches(var) if var else "")
        tbl = Path(tmp) / "ref.tbl"
        tbl.write_text(_tools_in_inches(tools))
        text = f"[RS274NGC]\nPARAMETER_FILE = {var_copy}\n"
        if subs:
            text += "SUBROUTINE_PATH = " + ":".join(str(s) for s in subs) + "\n"
        ini.write_text(text)
        result = Path(tmp) / "out.txt"
        for _attempt in range(3):   # under load rs274 now and then exits non-zero without a word: run it again
            run = subprocess.run(["rs274", "-g", "-i", str(ini), "-t", str(tbl), str(program), str(result)],
                                 capture_output=True, text=True, timeout=120, cwd=cwd or program.parent,
                                 stdin=subprocess.DEVNULL)
            if run.returncode == 0 or len(run.stdout.strip().splitlines()) > 1:
                break
        output = result.read_text() if result.exists() else ""
    scale, plane = 1.0, 1
    state = dict(feed=0.0, g5x=[0.0] * 6, g92=[0.0] * 6, rot=0.0, tool=[0.0] * 6)
    moves = []

    def six(args, lengths=3):
        v = [float(a) for a in args[:6]]
        return [x * scale for x in v[:lengths]] + v[lengths:]

    for raw in output.splitlines():
        m = _CALL.match(raw)
        if not m:
            continue
        name, args = m.group(1), [a.strip() for a in m.group(2).split(",")] if m.group(2).strip() else []
        if name == "USE_LENGTH_UNITS":
            scale = 25.4 if "INCHES" in args[0] else 1.0
        elif name == "SELECT_PLANE":
            plane = _PLANES.get(args[0], 1)
        elif name == "SET_FEED_RATE":
            state["feed"] = float(args[0]) * scale
        elif name == "SET_G5X_OFFSET":
            state["g5x"] = six(args[1:])
        elif name == "SET_G92_OFFSET":
            state["g92"] = six(args)
        elif name == "SET_XY_ROTATION":
            state["rot"] = float(args[0])
        elif name == "USE_TOOL_LENGTH_OFFSET":
            state["tool"] = six(" ".join(args).split())
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE"):
            kind = {"STRAIGHT_TRAVERSE": "rapid", "STRAIGHT_FEED": "linear"}.get(name, "probe")
            moves.append(dict(kind=kind, line=-1, end=six(args), **{k: list(v) if isinstance(v, list) else v
                                                                    for k, v in state.items()}))
        elif name == "ARC_FEED":
            v = [float(a) for a in args[:9]]
            u, w, n = {1: (0, 1, 2), 2: (1, 2, 0), 3: (2, 0, 1)}[plane]
            end, centre = [0.0] * 6, [None] * 3
            end[u], end[w], end[n] = v[0] * scale, v[1] * scale, v[5] * scale
            end[3:] = v[6:9]
            centre[u], centre[w] = v[2] * scale, v[3] * scale
            moves.append(dict(kind="arc", line=-1, end=end, centre=centre, rotation=int(v[4]), plane=plane,
                              **{k: list(v) if isinstance(v, list) else v for k, v in state.items()}))
    error = run.returncode != 0
    return Reference(moves=moves, error=error, line=-1, message=run.stdout.strip().splitlines()[-2]
                     if error and len(run.stdout.strip().splitlines()) > 1 else "", precision=5e-5)


def rotate(x, y, deg):
    t = math.radians(deg)
    return x * math.cos(t) - y * math.sin(t), x * math.sin(t) + y * math.cos(t)


def compare(blocks, ref: Reference, *, tol: float = 1e-6) -> list[str]:
    """Differences between feedlog's motion rows and LinuxCNC's canonical moves (empty: the same)."""
    motion = blocks[blocks["kind"].isin(["rapid", "linear", "arc_cw", "arc_ccw"])]
    problems: list[str] = []
    tol = max(tol, ref.precision * 1.01 * 25.4)
    if len(motion) != len(ref.moves):
        problems.append(f"{len(motion)} moves, LinuxCNC has {len(ref.moves)}")
    ends = motion[["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"]].to_numpy()
    work = motion[["wx_mm", "wy_mm", "wz_mm", "wa_deg", "wb_deg", "wc_deg"]].to_numpy()
    tool = motion[["tool_x_mm", "tool_y_mm", "tool_z_mm", "tool_a_deg", "tool_b_deg", "tool_c_deg"]].to_numpy() \
        if "tool_x_mm" in motion else np.zeros_like(work)
    rot = motion["rot_deg"].to_numpy() if "rot_deg" in motion else np.zeros(len(motion))
    kinds = motion["kind"].astype(str).to_numpy()
    lines = motion["line"].to_numpy()
    centres = motion[["cx_mm", "cy_mm", "cz_mm"]].to_numpy()
    turns = motion["turns"].to_numpy()
    for k, mv in enumerate(ref.moves[:len(motion)]):
        where = f"move {k} (line {mv['line']})"
        kind = "arc" if kinds[k].startswith("arc") else kinds[k]
        if kind != mv["kind"]:
            problems.append(f"{where}: {kinds[k]} vs LinuxCNC {mv['kind']}")
            continue
        if mv["line"] >= 0 and int(lines[k]) != int(mv["line"]):
            problems.append(f"{where}: on line {lines[k]} vs LinuxCNC line {mv['line']}")
        end = np.array(mv["end"])
        if not np.allclose(ends[k], end, atol=tol, rtol=1e-12):
            problems.append(f"{where}: end {ends[k].round(7).tolist()} vs {end.round(7).tolist()}")
        # machine position: R(p + g92) + g5x + tool, from LinuxCNC's offsets vs feedlog's columns
        g92, g5x, t = np.array(mv["g92"]), np.array(mv["g5x"]), np.array(mv["tool"])
        px, py = rotate(end[0] + g92[0], end[1] + g92[1], mv["rot"])
        ref_machine = np.r_[px, py, end[2:] + g92[2:]] + g5x + t
        ox, oy = rotate(ends[k][0], ends[k][1], rot[k])
        our_machine = np.r_[ox, oy, ends[k][2:]] + work[k] + tool[k]
        # rs274 rounds end point, offsets and tool length each to 4 decimals: up to 4 roundings add up
        if not np.allclose(our_machine, ref_machine, atol=tol * (4 if ref.precision else 1), rtol=1e-12):
            problems.append(f"{where}: machine position {our_machine.round(7).tolist()} vs "
                            f"{ref_machine.round(7).tolist()}")
        if kind == "arc":
            c = np.array([np.nan if v is None else v for v in mv["centre"]])
            known = ~np.isnan(c)
            if not np.allclose(centres[k][known], c[known], atol=tol, rtol=1e-12):
                problems.append(f"{where}: centre {centres[k].round(7).tolist()} vs {c.round(7).tolist()}")
            sign = 1 if kinds[k] == "arc_ccw" else -1
            if sign * int(turns[k]) != int(mv["rotation"]):
                problems.append(f"{where}: turns {sign * int(turns[k])} vs {mv['rotation']}")
        elif kind == "linear":
            feed = motion["feed_mm_min"].to_numpy()[k]
            if not motion["inverse_time"].to_numpy()[k] and abs(feed - mv["feed"]) > 1e-6 * max(1.0, mv["feed"]):
                problems.append(f"{where}: feed {feed} vs {mv['feed']}")
        if len(problems) > 12:
            problems.append("...")
            break
    return problems


needs_linuxcnc = _needs_linuxcnc()   # skip a test without LinuxCNC's gcode module (FEEDLOG_REQUIRE_LINUXCNC=1: fail)
