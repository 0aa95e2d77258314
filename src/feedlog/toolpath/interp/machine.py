"""The interpreter's machine model and what a block does to it, in LinuxCNC's order of execution.

State is kept as LinuxCNC keeps it: positions in program coordinates and program units (inch after
G20), work offsets (G54-G59.3, G92/G52), the XY rotation of G10 L2 R and the tool length offset
(G43) apart, parameters #5161-#5390 in machine units (mm). A block runs: feed mode, F, S, T, M codes
(tool change), then dwell, plane, units, tool length, coordinate system, path control, distance
modes, retract mode, G10/G28/G30/G52/G92, motion (lines, arcs, canned cycles), and stops. Every
motion goes to the Canon collector in mm.
"""

from __future__ import annotations

import math
from dataclasses import replace

from feedlog.toolpath.arcwords import (CENTER_ARC_RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_MM,
                                       spiral_too_large)
from feedlog.toolpath.interp import cycles, spline
from feedlog.toolpath.limits import MAX_ARC_TURNS, MAX_WORD, sci
from feedlog.toolpath.interp.block import Block
from feedlog.toolpath.interp.canon import (K_ARC_CCW, K_ARC_CW, K_DWELL, K_LINEAR, K_NONE, K_RAPID, Canon,
                                           Context)
from feedlog.toolpath.interp.codes import CYCLES, REFUSED_G, g_name
from feedlog.toolpath.interp.comp import Compensation
from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.tools import ToolTable

MM_PER_INCH = 25.4
INCH_PER_MM = 1.0 / 25.4
RADIUS_TOLERANCE_INCH = 0.00005
RADIUS_TOLERANCE_MM = RADIUS_TOLERANCE_INCH * MM_PER_INCH
TINY = 1e-12
PATH_EXACT_PATH, PATH_EXACT_STOP, PATH_CONTINUOUS = 0, 1, 2  # schema.PATH_MODES order


def rotate(x: float, y: float, theta_deg: float) -> tuple[float, float]:
    t = math.radians(theta_deg)
    return x * math.cos(t) - y * math.sin(t), x * math.sin(t) + y * math.cos(t)


def build_machine(*, tool_table=None, parameter_file=None, lookup=lambda _name: None,
                  arc_tolerance_mm: float | None = None, arc_tolerance_inch: float | None = None) -> Machine:
    """A machine model with its tool table, parameters (a parameter file loaded; `lookup` gives the
    front-end's predefined read-only names) and an empty Canon: what every front-end starts from."""
    from feedlog.toolpath.interp.params import Parameters

    params = Parameters(lookup)
    if parameter_file is not None:
        params.load_var(parameter_file)
    kw = {k: v for k, v in (("arc_tolerance_mm", arc_tolerance_mm), ("arc_tolerance_inch", arc_tolerance_inch))
          if v is not None}
    return Machine(params, Canon(), ToolTable.of(tool_table), **kw)


class Machine:
    """Modal state + the conversions. `emit(kind, end, centre, turns, dwell)` goes through `canon`."""

    def __init__(self, params, canon: Canon, tools: ToolTable, *,
                 arc_tolerance_mm: float = CENTER_ARC_RADIUS_TOLERANCE_MM,
                 arc_tolerance_inch: float = CENTER_ARC_RADIUS_TOLERANCE_INCH) -> None:
        self.P = params
        self.canon = canon
        self.tools = tools
        self.arc_tol_mm, self.arc_tol_inch = arc_tolerance_mm, arc_tolerance_inch
        self.pos = [0.0] * 6                 # current point, program coordinates, program units
        self.origin = [0.0] * 6              # active G5x offset (program units)
        self.g92 = [0.0] * 6                 # G92/G52 offset (program units)
        self.tool_offset = [0.0] * 6         # tool length offset (program units)
        self.rotation = 0.0                  # XY rotation of the active system (deg)
        self.origin_index = 1
        self.inch = False
        self.motion_mode = -1
        self.plane = 170
        self.incremental = False
        self.ijk_absolute = False
        self.feed_mode = 940
        self.feed = 0.0                      # F in program units/min
        self.speed = 0.0
        self.spindle = 5                     # M3/M4/M5
        self.control = PATH_CONTINUOUS
        self.tolerance = math.nan            # G64 P (program units), NaN: not given
        self.naive = math.nan
        self.selected_tool = -1
        self.current_tool = 0
        self.tlo_on = False
        self.cycle = {"r": 0.0, "cc": 0.0, "p": 0.0, "q": 0.0}   # a canned cycle's modal R, depth, P, Q
        self.cycle_il: float | None = None
        self.spline_ij = (0.0, 0.0)            # a G5 without I J starts with the last G5's -P, -Q
        self.nurbs_points: list = []           # G5.2 control points (x, y, weight), program units
        self.nurbs_order = 3
        self.line_src = 0
        self.unknown_systems: set[int] = set()   # selected systems whose offsets no parameter file gave
        self.comp = Compensation(self)
        self.emitted = 0                       # rows emitted or held so far
        self.last_move: tuple | None = None   # (end, offsets then) of the last move: where the tool is
        self._ctx_key = None
        self._ctx = 0
        self.retract_r_plane = True           # LinuxCNC starts retracting to the R plane (G99)
        selected = int(self.P.p[5220] + 0.0001)  # the parameter file's selected system (#5220), else G54
        self.origin_index = selected if 1 <= selected <= 9 else 1
        base = 5200 + 20 * self.origin_index
        for k in range(6):
            self.origin[k] = self._user_to_program(self.P.p[base + 1 + k], k)
        self.rotation = self.P.p[base + 10]

    # -- units -----------------------------------------------------------------------------------
    def _user_to_program(self, value: float, axis: int) -> float:
        return value * INCH_PER_MM if (axis < 3 and self.inch) else value

    def _program_to_user(self, value: float, axis: int) -> float:
        return value * MM_PER_INCH if (axis < 3 and self.inch) else value

    # -- output --------------------------------------------------------------------------------------
    def context(self) -> int:
        key = (self.control, self.tolerance, self.naive, self.plane, self.inch, self.speed, self.feed_mode,
               tuple(self.origin), tuple(self.g92), self.rotation, tuple(self.tool_offset), self.origin_index)
        if key != self._ctx_key:
            f = MM_PER_INCH if self.inch else 1.0
            gx, gy = rotate(self.g92[0], self.g92[1], self.rotation)
            work = (gx * f + self.origin[0] * f, gy * f + self.origin[1] * f, (self.g92[2] + self.origin[2]) * f,
                    self.g92[3] + self.origin[3], self.g92[4] + self.origin[4], self.g92[5] + self.origin[5])
            if self.control == PATH_CONTINUOUS:
                tol = self.tolerance * f
                merge = self.naive * f
            else:
                tol, merge = 0.0, math.nan
            tool = tuple(self.tool_offset[k] * (f if k < 3 else 1.0) for k in range(6))
            self._ctx = self.canon.context(Context(
                path_mode=self.control, tol_mm=tol, merge_tol_mm=merge, plane=self.plane // 10,
                units=int(self.inch), spindle_rpm=self.speed, inverse_time=self.feed_mode == 930, work=work,
                coord_system=self.origin_index, rot_deg=self.rotation, tool=tool))
            self._ctx_key = key
        return self._ctx

    def emit(self, kind: int, end, centre=(math.nan, math.nan, math.nan), turns: int = 0, dwell: float = 0.0,
             feed: float | None = None) -> None:
        self.emitted += 1
        if kind <= K_ARC_CCW:
            self.last_move = (tuple(end), self._offsets())
        if self.comp.queue:      # rows keep their order behind moves cutter compensation still holds
            self.comp.hold(kind, end, centre, turns if kind == K_ARC_CCW else -turns, dwell=dwell)
            return
        f = MM_PER_INCH if self.inch else 1.0
        if feed is None:
            feed = self.feed * f
        self.canon.rows.append((kind, self.line_src, self.context(),
                                end[0] * f, end[1] * f, end[2] * f, end[3], end[4], end[5],
                                centre[0] * f, centre[1] * f, centre[2] * f, turns, feed, dwell))

    def emit_none(self) -> None:
        """A row for a line that moves nothing: it stands where the tool is, which is the interpreter's
        point except after G40 (the tool stays at the compensated point) or a G88 (no retract)."""
        self.emit(K_NONE, self.tool_position())

    def tool_position(self) -> list[float]:
        """Where the tool is, in the program coordinates now in force (program units)."""
        if self.last_move is None or self.comp.queue:
            return self.pos
        end, offsets = self.last_move
        if offsets == self._offsets():
            return list(end)
        machine = self._machine_of(end, offsets)
        if offsets[4] != self.inch:
            k = MM_PER_INCH if offsets[4] else INCH_PER_MM
            machine = [v * k if i < 3 else v for i, v in enumerate(machine)]
        return self._relative(machine)

    def traverse(self, end) -> None:
        self.emit(K_RAPID, end)
        self.pos = list(end)

    def feed_to(self, end, feed: float | None = None) -> None:
        self.emit(K_LINEAR, end, feed=feed)
        self.pos = list(end)

    # -- the fast lane: a line of G0/G1, axis words and F ---------------------------------------------
    def fast_ok(self, motion: int) -> bool:
        """Whether a plain G0/G1 line can skip the general path (no compensation, per-minute feed, a G0/G1
        motion mode in force or given)."""
        return (not self.comp.side and self.feed_mode == 940
                and (motion in (0, 10) or (motion == -1 and self.motion_mode in (0, 10))))

    def fast_line(self, motion: int, v: dict) -> None:
        for letter, value in v.items():
            if abs(value) > MAX_WORD:
                raise InterpError(f"number out of range (beyond +-{sci(MAX_WORD)}): {letter.upper()}{value:.4g}")
        if "f" in v:
            f = v["f"]
            if f < 0.0:
                raise InterpError("negative F word used")
            self.feed = f
        if motion == -1:
            motion = self.motion_mode
        if motion == 10 and self.feed == 0.0:
            raise InterpError("cannot do G1 with zero feed rate")
        self.comp.arc_not_allowed = False
        self.cycle_il = None
        self.motion_mode = motion
        pos = self.pos
        if self.incremental:
            end = [pos[0] + v.get("x", 0.0), pos[1] + v.get("y", 0.0), pos[2] + v.get("z", 0.0),
                   pos[3] + v.get("a", 0.0), pos[4] + v.get("b", 0.0), pos[5] + v.get("c", 0.0)]
        else:
            end = [v.get("x", pos[0]), v.get("y", pos[1]), v.get("z", pos[2]), v.get("a", pos[3]),
                   v.get("b", pos[4]), v.get("c", pos[5])]
        self.emit(K_RAPID if motion == 0 else K_LINEAR, end)
        self.pos = end

    # -- one block ------------------------------------------------------------------------------------
    def execute(self, b: Block) -> bool:
        """Run a block. Returns True when it ends the program (M2/M30). Emits at least one row."""
        before = self.emitted
        g, m, v = b.g, b.m, b.v
        if b.motion in REFUSED_G:
            raise InterpError(REFUSED_G[b.motion])
        if "feed_mode" in g:
            if g["feed_mode"] != self.feed_mode:
                self.feed = 0.0 if (g["feed_mode"] == 930 or self.feed_mode == 930) else self.feed
            self.feed_mode = g["feed_mode"]
        if "f" in v and self.feed_mode != 930:
            self.feed = v["f"]
        if "s" in v:
            self.speed = v["s"]
        if "t" in v:
            t = int(v["t"])
            if t and self.tools.get(t) is None:
                raise InterpError(f"requested tool {t} not found in the tool table")
            self.selected_tool = t
        self._m_codes(b)
        if g.get("nonmodal") == 40:
            if v["p"] < 0:
                raise InterpError("negative dwell time")
            self.emit(K_DWELL, self.pos, dwell=v["p"])
        comp_on = bool(self.comp.side)
        if "plane" in g:
            if comp_on and g["plane"] != self.plane:
                raise InterpError("cannot change planes with cutter radius compensation on")
            self.plane = g["plane"]
        if "units" in g:
            if comp_on and (g["units"] == 200) != self.inch:
                raise InterpError("cannot change units with cutter radius compensation")
            self._units(g["units"] == 200)
        if "comp" in g:
            if g["comp"] == 400:
                self.comp.off()
            else:
                self.comp.on(g["comp"], v)
        comp_on = bool(self.comp.side)
        if comp_on and ("tool_length" in g or "coords" in g or "control" in g):
            what = ("tool offset" if "tool_length" in g else "coordinate systems" if "coords" in g
                    else "control mode")
            raise InterpError(f"cannot change {what} with cutter radius compensation on")
        if comp_on and g.get("nonmodal", -1) in (280, 300, 520, 920, 921, 922, 923):
            raise InterpError(f"cannot use {g_name(g['nonmodal'])} with cutter radius compensation on")
        if "tool_length" in g:
            self._tool_length(g["tool_length"], v)
        if "coords" in g:
            self._coordinate_system({540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8,
                                     593: 9}[g["coords"]])
        if "control" in g:
            self._control(g["control"], v)
        if "distance" in g:
            self.incremental = g["distance"] == 910
        if "ijk" in g:
            self.ijk_absolute = g["ijk"] == 901
        if "retract" in g:
            self.retract_r_plane = g["retract"] == 990
        mode0 = g.get("nonmodal", -1)
        if mode0 == 100:
            self._g10(v)
        elif mode0 in (280, 300):
            self._home(mode0, b)
        elif mode0 in (281, 301):
            self._save_home(mode0)
        elif mode0 in (520, 920):
            self._axis_offsets(mode0, v)
        elif mode0 in (921, 922, 923):
            self._axis_offsets(mode0, v)
        elif mode0 == 53:
            spline.nurbs_end(self)
        if b.motion != -1:
            self._motion(b)
        if m.get("toolchange") == 6:
            self.resync()
        end = False
        stop = m.get("stop", -1)
        if stop != -1:
            self.comp.stop()
        if stop in (2, 30, 99):
            end = True
        if self.emitted == before:
            self.emit_none()
        return end

    # -- M codes ------------------------------------------------------------------------------------
    def _m_codes(self, b: Block) -> None:
        m = b.m
        tc = m.get("toolchange", -1)
        if tc == 6:
            if self.selected_tool >= 0:
                self.current_tool = self.selected_tool
        elif tc == 61:
            q = b.v.get("q")
            if q is None:
                raise InterpError("need Q parameter with M61")
            t = int(round(q))
            if t and self.tools.get(t) is None:
                raise InterpError(f"requested tool {t} not found in the tool table")
            self.current_tool = t
        sp = m.get("spindle", -1)
        if sp in (3, 4, 5):
            self.spindle = sp

    # -- modal groups -----------------------------------------------------------------------------
    def _units(self, inch: bool) -> None:
        if inch == self.inch:
            return
        k = INCH_PER_MM if inch else MM_PER_INCH
        for arr in (self.pos, self.origin, self.g92, self.tool_offset):
            for i in range(3):
                arr[i] *= k
        self.feed *= k
        if not math.isnan(self.tolerance):
            self.tolerance *= k
        if not math.isnan(self.naive):
            self.naive *= k
        self.inch = inch

    def _control(self, code: int, v: dict) -> None:
        if code == 610:
            self.control = PATH_EXACT_PATH
        elif code == 611:
            self.control = PATH_EXACT_STOP
        else:
            self.control = PATH_CONTINUOUS
            p, q = v.get("p"), v.get("q")
            self.tolerance = p if p is not None and p >= 0 else math.nan
            self.naive = q if q is not None and q >= 0 else self.tolerance

    def _tool_length(self, code: int, v: dict) -> None:
        new = list(self.tool_offset)
        if code == 490:
            new = [0.0] * 6
        elif code == 430:
            tool = int(v["h"]) if "h" in v else self.current_tool
            if tool == 0:
                tool = self.current_tool
            entry = self.tools.get(tool) if tool else None
            if tool and entry is None:
                raise InterpError(f"requested tool {tool} not found in the tool table")
            offs = entry.offset if entry is not None else (0.0,) * 6
            new = [self._user_to_program(offs[k], k) for k in range(6)]
        elif code == 431:
            for k, a in enumerate("xyzabc"):
                if a in v:
                    new[k] = v[a]
        elif code == 432:
            if "h" in v:
                entry = self.tools.get(int(v["h"]))
                if entry is None:
                    raise InterpError(f"requested tool {int(v['h'])} not found in the tool table")
                for k in range(6):
                    new[k] += self._user_to_program(entry.offset[k], k)
            else:
                for k, a in enumerate("xyzabc"):
                    if a in v:
                        new[k] += v[a]
        dx = self.tool_offset[0] - new[0]
        dy = self.tool_offset[1] - new[1]
        dx, dy = rotate(dx, dy, -self.rotation)
        self.pos[0] += dx
        self.pos[1] += dy
        for k in range(2, 6):
            self.pos[k] += self.tool_offset[k] - new[k]
        self.tool_offset = new
        self.tlo_on = code != 490

    def _current_in_system(self, system: int) -> list[float]:
        p = self.P.p
        x = self.pos[0] + self.g92[0]
        y = self.pos[1] + self.g92[1]
        x, y = rotate(x, y, self.rotation)
        out = [x + self.origin[0], y + self.origin[1]] + [self.pos[k] + self.g92[k] + self.origin[k] for k in (2, 3, 4, 5)]
        for k in range(6):
            out[k] -= self._user_to_program(p[5201 + system * 20 + k], k)
        out[0], out[1] = rotate(out[0], out[1], -p[5210 + system * 20])
        if p[5210]:
            for k in range(6):
                out[k] -= self._user_to_program(p[5211 + k], k)
        return out

    def _coordinate_system(self, origin: int) -> None:
        if origin == self.origin_index:
            return
        p = self.P.p
        if not self.P.loaded and not any(p[5201 + origin * 20 + k] for k in range(6)):
            self.unknown_systems.add(origin)
        self.pos = self._current_in_system(origin)
        self.origin_index = origin
        p[5220] = float(origin)
        self.origin = [self._user_to_program(p[5201 + origin * 20 + k], k) for k in range(6)]
        self.rotation = p[5210 + origin * 20]

    def _g10(self, v: dict) -> None:
        lw = int(v.get("l", -1))
        if lw == 1:
            self._g10_l1(v)
            return
        if lw in (0, 10, 11):
            raise InterpError(f"G10 L{lw} (tool table data) is not supported")
        if "i" in v or "j" in v:
            raise InterpError("I J words not allowed with G10 L2")
        p = self.P.p
        p_int = int(v.get("p", 0) + 0.0001)
        if p_int == 0:
            p_int = self.origin_index
        if self.comp.side and p_int == self.origin_index:
            raise InterpError("cannot change the active coordinate system with cutter radius compensation on")
        base = 5200 + p_int * 20
        cx = self._current_in_system(p_int)
        if "r" in v:
            if lw == 20:
                raise InterpError("R not allowed in G10 L20")
            r = v["r"]
            p[base + 10] = r
        else:
            r = p[base + 10]
        vals = [0.0] * 6
        if lw == 20:
            x = v.get("x", cx[0])
            y = v.get("y", cx[1])
            ox, oy = rotate(cx[0], cx[1], r)
            x, y = rotate(x, y, r)
            x = ox + self._user_to_program(p[base + 1], 0) - x
            y = oy + self._user_to_program(p[base + 2], 1) - y
            p[base + 1] = self._program_to_user(x, 0)
            p[base + 2] = self._program_to_user(y, 1)
            vals[0], vals[1] = x, y
            if p_int == self.origin_index:
                self.pos[0], self.pos[1] = rotate(self.pos[0], self.pos[1], self.rotation)
                self.rotation = 0.0
        else:
            for k, a in ((0, "x"), (1, "y")):
                if a in v:
                    vals[k] = v[a]
                    p[base + 1 + k] = self._program_to_user(v[a], k)
                else:
                    vals[k] = self._user_to_program(p[base + 1 + k], k)
        for k, a in ((2, "z"), (3, "a"), (4, "b"), (5, "c")):
            if a in v:
                val = v[a]
                if lw == 20:
                    val = cx[k] + self._user_to_program(p[base + 1 + k], k) - val
                vals[k] = val
                p[base + 1 + k] = self._program_to_user(val, k)
            else:
                vals[k] = self._user_to_program(p[base + 1 + k], k)
        if p_int == self.origin_index:
            self.pos[0], self.pos[1] = rotate(self.pos[0], self.pos[1], self.rotation)
            for k in range(6):
                self.pos[k] += self.origin[k]
            self.origin = vals
            for k in range(6):
                self.pos[k] -= vals[k]
            self.pos[0], self.pos[1] = rotate(self.pos[0], self.pos[1], -r)
            self.rotation = r

    def _g10_l1(self, v: dict) -> None:
        """G10 L1 P<tool>: the tool table entry's offsets (X-C, program units) and radius R, as LinuxCNC's
        `convert_setup_tool` sets them; a G43 later in the program reads the new entry."""
        number = round(v.get("p", 0.0))
        entry = self.tools.get(number) if number else None
        if entry is None:
            raise InterpError(f"requested tool {number} not found in the tool table")
        if not any(a in v for a in "xyzabcrqij"):
            raise InterpError("G10 L1 without offsets has no effect")
        offset = list(entry.offset)
        for k, a in enumerate("xyzabc"):
            if a in v:
                offset[k] = self._program_to_user(v[a], k)
        diameter = self._program_to_user(v["r"], 0) * 2.0 if "r" in v else entry.diameter
        self.tools.tools[number] = replace(entry, offset=tuple(offset), diameter=diameter)

    def _axis_offsets(self, code: int, v: dict) -> None:
        p = self.P.p
        if code in (520, 920):
            p[5210] = 1.0
            for k, a in enumerate("xyzabc"):
                if a in v:
                    if code == 520:
                        self.pos[k] += self.g92[k] - v[a]
                        self.g92[k] = v[a]
                    else:
                        self.g92[k] = self.pos[k] + self.g92[k] - v[a]
                        self.pos[k] = v[a]
            for k in range(6):
                p[5211 + k] = self._program_to_user(self.g92[k], k)
        elif code in (921, 922):
            p[5210] = 0.0
            for k in range(6):
                self.pos[k] += self.g92[k]
                self.g92[k] = 0.0
            if code == 921:
                for k in range(9):
                    p[5211 + k] = 0.0
        else:  # G92.3
            p[5210] = 1.0
            for k in range(6):
                off = self._user_to_program(p[5211 + k], k)
                self.pos[k] = self.pos[k] + self.g92[k] - off
                self.g92[k] = off

    def _relative(self, machine: list[float]) -> list[float]:
        """Program coordinates of a machine-coordinate point (find_relative)."""
        out = list(machine)
        for k in range(6):
            out[k] -= self.origin[k] + self.tool_offset[k]
        out[0], out[1] = rotate(out[0], out[1], -self.rotation)
        for k in range(6):
            out[k] -= self.g92[k]
        return out

    def _home(self, code: int, b: Block) -> None:
        end = self._ends(b)
        self.traverse(end)
        base = 5161 if code == 280 else 5181
        home = self._relative([self._user_to_program(self.P.p[base + k], k) for k in range(6)])
        given = [a in b.v for a in "xyzabc"]
        target = list(end)
        if not any(given):
            target = home
        else:
            for k in range(6):
                if given[k]:
                    target[k] = home[k]
        self.traverse(target)

    def _save_home(self, code: int) -> None:
        base = 5161 if code == 281 else 5181
        machine = self._machine_position()
        for k in range(6):
            self.P.p[base + k] = self._program_to_user(machine[k], k)

    def _machine_position(self) -> list[float]:
        return self._machine_of(self.pos, self._offsets())

    def _offsets(self) -> tuple:
        return (tuple(self.g92), self.rotation, tuple(self.origin), tuple(self.tool_offset), self.inch)

    @staticmethod
    def _machine_of(p, offsets) -> list[float]:
        """Machine coordinates of program point `p` under `offsets` (from _offsets()), in their units."""
        g92, rotation, origin, tool, _ = offsets
        x, y = rotate(p[0] + g92[0], p[1] + g92[1], rotation)
        out = [x, y] + [p[k] + g92[k] for k in (2, 3, 4, 5)]
        return [out[k] + origin[k] + tool[k] for k in range(6)]

    def resync(self) -> None:
        """After a tool change LinuxCNC re-reads where the machine is: the interpreter's point becomes the
        machine position of the last move under the offsets now in force (a G40 before it had only moved
        the interpreter's idea of the point, not the tool)."""
        if self.last_move is not None:
            self.pos = list(self.tool_position())

    # -- motion -------------------------------------------------------------------------------------
    def _ends(self, b: Block) -> list[float]:
        """find_ends: the block's end point (program coordinates, program units)."""
        v = b.v
        pos = self.pos
        if b.g.get("nonmodal") == 530:
            if "@" in v or "^" in v:
                raise InterpError("cannot use polar coordinates with G53")
            if b.g.get("distance") == 910 or (b.g.get("distance") != 900 and self.incremental):
                raise InterpError("cannot use G53 incremental")
            cx, cy = rotate(pos[0] + self.g92[0], pos[1] + self.g92[1], self.rotation)
            x = v["x"] - self.origin[0] - self.tool_offset[0] if "x" in v else cx
            y = v["y"] - self.origin[1] - self.tool_offset[1] if "y" in v else cy
            x, y = rotate(x, y, -self.rotation)
            out = [x - self.g92[0], y - self.g92[1]]
            out.append(v["z"] - self.origin[2] - self.g92[2] - self.tool_offset[2] if "z" in v else pos[2])
            for k, a in ((3, "a"), (4, "b"), (5, "c")):
                out.append(v[a] - self.origin[k] - self.g92[k] if a in v else pos[k])
            return out
        base = pos
        comp = self.comp
        if comp.side and not comp.first:     # unprogrammed in-plane axes continue from the programmed point
            base = list(pos)
            base[0] = comp.program[0]
            if self.plane == 170:
                base[1] = comp.program[1]
            elif self.plane == 180:
                base[2] = comp.program[2]
        if not self.incremental:
            x = v.get("x", base[0])
            y = v.get("y", base[1])
            if "@" in v and "^" in v:
                r, t = v["@"], math.radians(v["^"])
                x, y = r * math.cos(t), r * math.sin(t)
            elif "@" in v:
                if x == 0 and y == 0:
                    raise InterpError("must specify angle in polar coordinate if at the origin")
                t = math.atan2(y, x)
                x, y = v["@"] * math.cos(t), v["@"] * math.sin(t)
            elif "^" in v:
                r = math.hypot(y, x)
                t = math.radians(v["^"])
                x, y = r * math.cos(t), r * math.sin(t)
            return [x, y, v.get("z", base[2]), v.get("a", pos[3]), v.get("b", pos[4]), v.get("c", pos[5])]
        x = base[0] + v.get("x", 0.0)
        y = base[1] + v.get("y", 0.0)
        if "@" in v:
            if x == 0 and y == 0:
                raise InterpError("incremental motion with polar coordinates is indeterminate when at the origin")
            t = math.atan2(y, x)
            r = math.hypot(y, x) + v["@"]
            x, y = r * math.cos(t), r * math.sin(t)
        if "^" in v:
            if x == 0 and y == 0:
                raise InterpError("G91 motion with polar coordinates is indeterminate when at the origin")
            t = math.atan2(y, x) + math.radians(v["^"])
            r = math.hypot(y, x)
            x, y = r * math.cos(t), r * math.sin(t)
        return [x, y, base[2] + v.get("z", 0.0), pos[3] + v.get("a", 0.0), pos[4] + v.get("b", 0.0),
                pos[5] + v.get("c", 0.0)]

    def _motion(self, b: Block) -> None:
        motion = b.motion
        if motion not in CYCLES:
            self.cycle_il = None
        if motion in (0, 10):
            self._straight(motion, b)
        elif motion in (20, 30):
            self._arc(motion, b)
        elif motion == 800:
            self.motion_mode = 800
        elif motion in CYCLES:
            cycles.convert_cycle(self, motion, b)
        elif motion in (50, 51):
            spline.convert_spline(self, motion, b)
        elif motion == 52:
            spline.nurbs_point_line(self, b)
        else:
            raise InterpError(f"motion {g_name(motion)} is not supported")

    def _feed_checks(self, b: Block, what: str) -> None:
        if self.feed_mode == 940 and self.feed == 0.0:
            raise InterpError(f"cannot do {what} with zero feed rate")
        if self.feed_mode == 930 and "f" not in b.v:
            raise InterpError(f"F word missing with inverse time {what}")

    def _straight(self, motion: int, b: Block) -> None:
        if motion == 10:
            self._feed_checks(b, "G1")
        self.comp.arc_not_allowed = False
        self.motion_mode = motion
        end = self._ends(b)
        if self.comp.active:
            if b.g.get("nonmodal") == 530:
                raise InterpError("cannot use G53 with cutter radius compensation")
            self.comp.straight(motion, end)
            return
        if motion == 0:
            self.traverse(end)
            return
        feed = None
        if self.feed_mode == 930:
            f = MM_PER_INCH if self.inch else 1.0
            d = [end[k] - self.pos[k] for k in range(6)]
            length = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
            if length < 1e-12:
                length = math.sqrt(d[3] ** 2 + d[4] ** 2 + d[5] ** 2)
                f = 1.0
            feed = max(0.1, length * b.v["f"]) * f
        self.feed_to(end, feed)

    def _arc(self, motion: int, b: Block) -> None:
        v = b.v
        if self.comp.arc_not_allowed:
            raise InterpError("the move just after exiting cutter compensation mode must be straight, not an arc")
        ijk = "i" in v or "j" in v or "k" in v
        if "r" not in v and not ijk:
            raise InterpError("R, I, J, and K words all missing for arc")
        if "r" in v and ijk:
            raise InterpError("mixed radius-ijk format for arc")
        self._feed_checks(b, "an arc")
        u, w, n = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}[self.plane]
        letters = "ijk"
        if ijk:
            if letters[n] in v:
                raise InterpError(f"{letters[n].upper()} word given for arc in {g_name(self.plane)} plane")
            for k in (u, w):
                if letters[k] not in v and self.ijk_absolute:
                    raise InterpError(f"{letters[k].upper()} word missing in absolute center arc")
        else:
            names = "xyz"
            if names[u] not in v and names[w] not in v and not ("@" in v or "^" in v):
                raise InterpError(f"{names[u].upper()} and {names[w].upper()} words missing for arc in "
                                  f"{g_name(self.plane)} plane")
        end = self._ends(b)
        self.motion_mode = motion
        p_words = int(round(v["p"])) if "p" in v else 1
        if p_words > MAX_ARC_TURNS:
            raise InterpError(f"arc P (turns) must be a whole number from 1 to {MAX_ARC_TURNS}")
        if self.comp.active and self.plane in (170, 180):
            self.comp.arc(motion, end, v, p_words)
            return
        s1, s2 = self.pos[u], self.pos[w]
        e1, e2 = end[u], end[w]
        radius_tol = RADIUS_TOLERANCE_INCH if self.inch else RADIUS_TOLERANCE_MM
        if "r" in v:
            c1, c2 = _arc_centre_r(motion, s1, s2, e1, e2, v["r"], radius_tol)
        else:
            o1, o2 = v.get(letters[u], 0.0), v.get(letters[w], 0.0)
            spiral = self.arc_tol_inch if self.inch else self.arc_tol_mm
            c1, c2 = _arc_centre_ijk(s1, s2, e1, e2, self.ijk_absolute, o1, o2, radius_tol, spiral)
        centre = [0.0, 0.0, 0.0]
        centre[u], centre[w], centre[n] = c1, c2, self.pos[n]
        feed = None
        if self.feed_mode == 930:
            f = MM_PER_INCH if self.inch else 1.0
            r0 = math.hypot(s1 - c1, s2 - c2)
            a0 = math.atan2(s2 - c2, s1 - c1)
            a1 = math.atan2(e2 - c2, e1 - c1)
            sweep = (a1 - a0) if motion == 30 else (a0 - a1)
            sweep %= 2 * math.pi
            if sweep <= 1e-12:
                sweep = 2 * math.pi
            sweep += 2 * math.pi * (p_words - 1)
            length = math.hypot(r0 * sweep, end[n] - self.pos[n])
            feed = max(0.1, length * v["f"]) * f
        self.emit(K_ARC_CCW if motion == 30 else K_ARC_CW, end, centre, turns=p_words, feed=feed)
        self.pos = list(end)


def _arc_centre_ijk(s1, s2, e1, e2, absolute, o1, o2, radius_tol, spiral_abs):
    c1, c2 = (o1, o2) if absolute else (s1 + o1, s2 + o2)
    r1 = math.hypot(c1 - s1, c2 - s2)
    r2 = math.hypot(c1 - e1, c2 - e2)
    if r1 < radius_tol or r2 < radius_tol:
        raise InterpError(f"zero-radius arc: start=({s1:.4f},{s2:.4f}) center=({c1:.4f},{c2:.4f}) "
                          f"end=({e1:.4f},{e2:.4f})")
    if spiral_too_large(r1, r2, spiral_abs):
        abs_err = abs(r1 - r2)
        rel_err = abs_err / max(r1, r2)
        raise InterpError(f"radius to end of arc differs from radius to start: start=({s1:.4f},{s2:.4f}) "
                          f"center=({c1:.4f},{c2:.4f}) end=({e1:.4f},{e2:.4f}) r1={r1:.4f} r2={r2:.4f} "
                          f"abs_err={abs_err:.4g} rel_err={rel_err * 100:.4f}% (tolerance {spiral_abs:.4g})")
    return c1, c2


def _arc_centre_r(motion, s1, s2, e1, e2, radius, tol):
    if e1 == s1 and e2 == s2:
        raise InterpError("current point same as end point of arc")
    abs_r = abs(radius)
    m1, m2 = (e1 + s1) / 2.0, (e2 + s2) / 2.0
    half = math.hypot(m1 - e1, m2 - e2)
    if half - abs_r > tol:
        raise InterpError("arc radius too small to reach end point")
    if half / abs_r > 1 - TINY:
        half = abs_r
    if (motion == 20 and radius > 0) or (motion == 30 and radius < 0):
        theta = math.atan2(e2 - s2, e1 - s1) - math.pi / 2
    else:
        theta = math.atan2(e2 - s2, e1 - s1) + math.pi / 2
    turn2 = math.asin(half / abs_r)
    offset = abs_r * math.cos(turn2)
    return m1 + offset * math.cos(theta), m2 + offset * math.sin(theta)
