"""Cutter radius compensation (G41/G42, G41.1/G42.1) as LinuxCNC computes it, in the XY and XZ planes.

The tool centre runs one tool radius to the left (G41) or right (G42) of the programmed path. Moves are
held in a queue until the next move shows the corner: at a convex corner an arc around the programmed
corner point is inserted; at a concave corner the held moves are shortened to where the tool meets the
next move (line-line, line-arc, arc-arc), and moves that would have to run backwards are errors
("cannot be reached by the tool without gouging"), as in LinuxCNC. The entry move (the first after
G41/G42) goes to the point one radius beside the programmed end, perpendicular to the entry direction;
after G40 the next move starts from the compensated point and must be straight.

Coordinates here are the plane's (first, second) axes: X, Y in G17; Z, X in G18 (LinuxCNC's order).
Everything is in program units; held moves become block-table rows when the queue is flushed.
"""

from __future__ import annotations

import math

from feedlog.toolpath.interp.errors import InterpError

RIGHT, LEFT = 1, 2
TOLERANCE_CONCAVE_CORNER = 0.05
TOLERANCE_EQUAL = 0.0001
_PLANE_AXES = {170: (0, 1, 2), 180: (2, 0, 1)}


def inside(side: int, turn: int) -> bool:
    return (side == LEFT and turn > 0) or (side == RIGHT and turn < 0)


def find_turn(x1, y1, cx, cy, turn, x2, y2) -> float:
    """Signed swept angle (rad) of an arc of `turn` turns from (x1, y1) to (x2, y2) around (cx, cy)."""
    if turn == 0:
        return 0.0
    alpha = math.atan2(y1 - cy, x1 - cx)
    beta = math.atan2(y2 - cy, x2 - cx)
    if turn > 0:
        if beta <= alpha:
            beta += 2 * math.pi
        return beta - alpha + (turn - 1) * 2 * math.pi
    if alpha <= beta:
        alpha += 2 * math.pi
    return beta - alpha + (turn + 1) * 2 * math.pi


class Held:
    """A move (or a row between moves) waiting in the queue. `end` (6, program units) may still move in
    the plane; `direction` is the programmed direction of a straight move; arcs keep centre and turn."""

    __slots__ = ("kind", "src", "ctx", "end", "centre", "turn", "sweep", "feed", "dwell", "direction", "inch")

    def __init__(self, kind, src, ctx, end, centre, turn, sweep, feed, dwell, direction, inch):
        self.kind, self.src, self.ctx, self.end, self.centre = kind, src, ctx, list(end), list(centre)
        self.turn, self.sweep, self.feed, self.dwell, self.direction, self.inch = turn, sweep, feed, dwell, direction, inch


class Compensation:
    """The compensation state of one machine (toolpath.interp.machine.Machine)."""

    def __init__(self, machine) -> None:
        self.m = machine
        self.side = 0
        self.radius = 0.0
        self.first = True
        self.program = [0.0, 0.0, 0.0]      # programmed point (X Y Z) while compensation is on
        self.arc_not_allowed = False
        self.queue: list[Held] = []
        self.endpoint = (0.0, 0.0)
        self.endpoint_valid = False

    @property
    def active(self) -> bool:
        return bool(self.side) and self.radius > 0.0

    def axes(self) -> tuple[int, int, int]:
        axes = _PLANE_AXES.get(self.m.plane)
        if axes is None:
            raise InterpError("BUG: cutter compensation in a plane other than G17/G18")
        return axes

    def current(self) -> tuple[float, float, float]:
        u, v, n = self.axes()
        p = self.m.pos
        return p[u], p[v], p[n]

    def programmed(self) -> tuple[float, float, float]:
        u, v, n = self.axes()
        p = self.program
        return p[u], p[v], p[n]

    def set_programmed(self, a: float, b: float, c: float) -> None:
        u, v, n = self.axes()
        self.program[u], self.program[v], self.program[n] = a, b, c

    def point(self, a: float, b: float, c: float, rest) -> list[float]:
        u, v, n = self.axes()
        p = [0.0] * 6
        p[u], p[v], p[n] = a, b, c
        p[3:] = rest
        return p

    # -- on and off -------------------------------------------------------------------------------
    def on(self, code: int, v: dict) -> None:
        m = self.m
        if m.plane not in (170, 180):
            raise InterpError("radius compensation is only allowed in the XY or XZ plane")
        if self.side:
            raise InterpError("cannot turn cutter radius compensation on when it is on")
        side = LEFT if code in (410, 411) else RIGHT
        if code in (411, 421):
            if "d" not in v:
                raise InterpError(f"G{code // 10}.1 with no D word")
            radius = v["d"] / 2.0
        else:
            if "d" in v:
                tool = round(v["d"])
                if abs(tool - v["d"]) >= 0.0001:
                    raise InterpError(f"G{code // 10} requires D word to be a whole number")
                if tool < 0:
                    raise InterpError("negative D word tool radius index used")
            else:
                tool = 0
            if tool == 0:
                tool = m.current_tool
            entry = m.tools.get(tool) if tool else None
            if tool and entry is None:
                raise InterpError(f"requested tool {tool} not found in the tool table")
            diameter = entry.diameter if entry is not None else 0.0
            radius = m._user_to_program(diameter, 0) / 2.0
        if radius < 0.0:
            radius = -radius
            side = LEFT if side == RIGHT else RIGHT
        self.radius, self.side = radius, side

    def off(self) -> None:
        m = self.m
        if self.side and self.radius > 0.0 and not self.first:
            cx, cy, _ = self.current()
            self.move_endpoint_and_flush(cx, cy)
            self.dequeue()
            m.pos[0], m.pos[1], m.pos[2] = self.program
            self.arc_not_allowed = True
        self.side = 0
        self.first = True

    def stop(self) -> None:
        """M0/M1/M2/M30/M60: the held moves go out as they are."""
        if self.queue:
            cx, cy, _ = self.current()
            self.move_endpoint_and_flush(cx, cy)
            self.dequeue()

    # -- the queue ---------------------------------------------------------------------------------
    def hold(self, kind: int, end, centre=(math.nan, math.nan, math.nan), turn: int = 0, sweep: float = 0.0,
             dwell: float = 0.0, direction=(0.0, 0.0)) -> None:
        m = self.m
        m.emitted += 1
        f = 25.4 if m.inch else 1.0
        if kind <= 3:
            m.last_move = (list(end), m._offsets())
        self.queue.append(Held(kind, m.line_src, m.context(), end, centre, turn, sweep, m.feed * f, dwell,
                               direction, m.inch))

    def dequeue(self) -> None:
        self.endpoint_valid = False
        rows = self.m.canon.rows
        for q in self.queue:
            f = 25.4 if q.inch else 1.0
            e, c = q.end, q.centre
            rows.append((q.kind, q.src, q.ctx, e[0] * f, e[1] * f, e[2] * f, e[3], e[4], e[5],
                         c[0] * f, c[1] * f, c[2] * f, abs(q.turn), q.feed, q.dwell))
        self.queue.clear()

    def set_endpoint(self, x: float, y: float) -> None:
        self.endpoint = (x, y)
        self.endpoint_valid = True

    def move_endpoint_and_flush(self, x: float, y: float) -> None:
        u, v, _ = self.axes()
        mm = not self.m.inch
        for q in self.queue:
            if q.kind in (2, 3):   # arcs
                c1, c2 = q.centre[u], q.centre[v]
                r1 = math.hypot(q.end[u] - c1, q.end[v] - c2)
                r2 = math.hypot(x - c1, y - c2)
                l2 = find_turn(self.endpoint[0], self.endpoint[1], c1, c2, q.turn, x, y)
                if abs(r1 - r2) > 0.01:
                    raise InterpError(f"BUG: cutter compensation has generated an invalid arc with mismatched "
                                      f"radii r1 {r1:f} r2 {r2:f}")
                if q.sweep != 0.0 and self.endpoint_valid and abs(l2) > abs(q.sweep) + (0.0254 if mm else 0.001):
                    raise InterpError("arc move in concave corner cannot be reached by the tool without gouging")
            elif q.kind in (0, 1):
                x2, y2 = x - self.endpoint[0], y - self.endpoint[1]
                dot = q.direction[0] * x2 + q.direction[1] * y2
                if self.endpoint_valid and dot < 0:
                    what = "straight traverse" if q.kind == 0 else "straight feed"
                    raise InterpError(f"{what} in concave corner cannot be reached by the tool without gouging")
            q.end[u], q.end[v] = x, y    # rows between held moves stand where the tool then is
        self.dequeue()
        self.set_endpoint(x, y)

    # -- straight moves -------------------------------------------------------------------------------
    def straight(self, move: int, end: list[float]) -> None:
        """A G0/G1 to the programmed `end` (6, program coordinates) with compensation on."""
        u, v, n = self.axes()
        px, py, pz = end[u], end[v], end[n]
        kind = 0 if move == 0 else 1
        if self.first:
            cx, cy, cz = self.current()
            distance = math.hypot(px - cx, py - cy)
            if distance <= self.radius:
                raise InterpError("length of cutter compensation entry move is not greater than the tool radius")
            alpha = math.atan2(py - cy, px - cx) + (math.pi / 2 if self.side == LEFT else -math.pi / 2)
            ex, ey = px + self.radius * math.cos(alpha), py + self.radius * math.sin(alpha)
            self.set_endpoint(cx, cy)
            self.hold(kind, self.point(ex, ey, pz, end[3:]), direction=(math.cos(alpha), math.sin(alpha)))
            self.first = False
            self._moved_to(ex, ey, pz, end)
            self.set_programmed(px, py, pz)
            return
        cx, cy, cz = self.current()
        opx, opy, opz = self.programmed()
        if py == opy and px == opx:     # no motion in the plane
            self.hold(kind, self.point(cx, cy, pz, end[3:]), direction=(px - opx, py - opy))
            self._moved_to(cx, cy, pz, end)
            self.set_programmed(px, py, pz)
            return
        side, radius = self.side, self.radius
        small = TOLERANCE_CONCAVE_CORNER
        theta = math.atan2(cy - opy, cx - opx)
        alpha = math.atan2(py - opy, px - opx)
        if side == LEFT:
            if theta < alpha:
                theta += 2 * math.pi
            beta = theta - alpha - math.pi / 2
            gamma = math.pi / 2
        else:
            if alpha < theta:
                alpha += 2 * math.pi
            beta = alpha - theta - math.pi / 2
            gamma = -math.pi / 2
        ex, ey = px + radius * math.cos(alpha + gamma), py + radius * math.sin(alpha + gamma)
        mid_x, mid_y = opx + radius * math.cos(alpha + gamma), opy + radius * math.sin(alpha + gamma)
        front_arc = bool(self.queue) and self.queue[0].kind in (2, 3)
        if beta < -small or beta > math.pi + small:
            concave = True
        elif beta > math.pi - small and front_arc and (
                (side == RIGHT and self.queue[0].turn > 0) or (side == LEFT and self.queue[0].turn < 0)):
            concave = True
        else:
            concave = False
        if not concave and beta > small:       # convex corner: an arc around the programmed point
            self.move_endpoint_and_flush(cx, cy)
            if move == 10:
                self.hold(3 if side == RIGHT else 2, self.point(mid_x, mid_y, cz, end[3:]),
                          centre=self.point(opx, opy, cz, (0, 0, 0))[:3], turn=1 if side == RIGHT else -1)
            else:
                self.hold(0, self.point(mid_x, mid_y, cz, end[3:]))
            self.dequeue()
            self.set_endpoint(mid_x, mid_y)
        elif concave:
            if not front_arc:
                halfcorner = (beta + math.pi) / 2.0
                if halfcorner == 0.0:
                    raise InterpError("zero degree inside corner is invalid for cutter compensation")
                retreat = radius / math.tan(halfcorner)
                mx, my = cx + retreat * math.cos(theta + gamma), cy + retreat * math.sin(theta + gamma)
                self.move_endpoint_and_flush(mx, my)
            else:
                prev = self.queue[0]
                pc1, pc2 = prev.centre[u], prev.centre[v]
                oldrad = math.hypot(pc2 - prev.end[v], pc1 - prev.end[u])
                base_dir = math.atan2(py - opy, px - opx)
                th = base_dir + math.pi / 2 if prev.turn > 0 else base_dir - math.pi / 2
                phi = math.atan2(pc2 - opy, pc1 - opx)
                oldrad_uncomp = oldrad + radius if inside(side, prev.turn) else oldrad - radius
                d = oldrad_uncomp * math.cos(th - phi)
                if inside(side, prev.turn):
                    ratio = (d - radius) / oldrad
                    if ratio > 1.0 or ratio < -1.0:
                        raise InterpError("arc to straight motion makes a corner the compensated tool can't fit "
                                          "in without gouging")
                    angle = (-math.acos(ratio) if prev.turn > 0 else math.acos(ratio)) + th + math.pi
                else:
                    ratio = (d + radius) / oldrad
                    if ratio > 1.0 or ratio < -1.0:
                        raise InterpError("arc to straight motion makes a corner the compensated tool can't fit "
                                          "in without gouging")
                    angle = (math.acos(ratio) if prev.turn > 0 else -math.acos(ratio)) + th + math.pi
                self.move_endpoint_and_flush(pc1 + oldrad * math.cos(angle), pc2 + oldrad * math.sin(angle))
        else:
            self.dequeue()
            self.set_endpoint(cx, cy)
        self.hold(kind, self.point(ex, ey, pz, end[3:]), direction=(px - opx, py - opy))
        self._moved_to(ex, ey, pz, end)
        self.set_programmed(px, py, pz)

    def _moved_to(self, a: float, b: float, c: float, end) -> None:
        u, v, n = self.axes()
        p = self.m.pos
        p[u], p[v], p[n] = a, b, c
        p[3:] = end[3:]

    # -- arcs -------------------------------------------------------------------------------------
    def arc(self, move: int, end: list[float], v: dict, p_turns: int) -> None:
        from feedlog.toolpath.interp.machine import (RADIUS_TOLERANCE_INCH, RADIUS_TOLERANCE_MM, _arc_centre_ijk,
                                                     _arc_centre_r)
        m = self.m
        u, w, n = self.axes()
        letters = "ijk"
        ex, ey, ez = end[u], end[w], end[n]
        o1, o2 = v.get(letters[u], 0.0), v.get(letters[w], 0.0)
        side, tool_radius = self.side, self.radius
        spiral = m.arc_tol_inch if m.inch else m.arc_tol_mm
        radius_tol = RADIUS_TOLERANCE_INCH if m.inch else RADIUS_TOLERANCE_MM
        tool_outside_ok = not ((side == LEFT and move == 30) or (side == RIGHT and move == 20))
        turn = (1 if move == 30 else -1) * p_turns
        cx, cy, cz = self.current()
        if self.first:
            if math.hypot(ex - cx, ey - cy) <= tool_radius:
                raise InterpError("radius of cutter compensation entry arc is not greater than the tool radius")
            if "r" in v:
                if abs(v["r"]) <= tool_radius and not tool_outside_ok:
                    raise InterpError("tool radius not less than arc radius with comp")
                c1, c2 = _arc_centre_r(move, cx, cy, ex, ey, v["r"], radius_tol)
            else:
                c1, c2 = _arc_centre_ijk(cx, cy, ex, ey, m.ijk_absolute, o1, o2, radius_tol, spiral)
                if math.hypot(c1 - cx, c2 - cy) <= tool_radius and not tool_outside_ok:
                    raise InterpError("tool radius not less than arc radius with comp")
            if inside(side, turn):
                gamma = math.atan2(c2 - ey, c1 - ex)
            else:
                gamma = math.atan2(ey - c2, ex - c1)
            self.first = False
            self.set_programmed(ex, ey, ez)
            nx, ny = ex + tool_radius * math.cos(gamma), ey + tool_radius * math.sin(gamma)
            b_len = math.hypot(cy - ny, cx - nx) / 2.0
            ab_ang = math.atan2(c2 - ny, c1 - nx)
            a_ang = math.atan2(cy - ny, cx - nx) - ab_ang
            if abs(math.cos(a_ang)) < TOLERANCE_EQUAL:
                raise InterpError("tool radius not less than arc radius with comp")
            c_len = b_len / math.cos(a_ang)
            c1, c2 = nx + c_len * math.cos(ab_ang), ny + c_len * math.sin(ab_ang)
            if abs(math.hypot(c1 - nx, c2 - ny) - math.hypot(c1 - cx, c2 - cy)) > spiral:
                raise InterpError("bug in tool radius comp")
            self.hold(3 if turn > 0 else 2, self.point(nx, ny, ez, end[3:]),
                      centre=self.point(c1, c2, cz, (0, 0, 0))[:3], turn=turn,
                      sweep=find_turn(cx, cy, c1, c2, turn, nx, ny))
            self._moved_to(nx, ny, ez, end)
            return
        opx, opy, opz = self.programmed()
        if "r" in v:
            c1, c2 = _arc_centre_r(move, opx, opy, ex, ey, v["r"], radius_tol)
        else:
            c1, c2 = _arc_centre_ijk(opx, opy, ex, ey, m.ijk_absolute, o1, o2, radius_tol, spiral)
        arc_radius = math.hypot(c1 - ex, c2 - ey)
        theta = math.atan2(cy - opy, cx - opx)
        theta = theta - math.pi / 2 if side == LEFT else theta + math.pi / 2
        delta = math.atan2(c2 - opy, c1 - opx)
        alpha = delta - math.pi / 2 if move == 30 else delta + math.pi / 2
        beta = theta - alpha if side == LEFT else alpha - theta
        if beta > 1.5 * math.pi:
            beta -= 2 * math.pi
        elif beta < -math.pi / 2:
            beta += 2 * math.pi
        if (side == LEFT and move == 30) or (side == RIGHT and move == 20):
            gamma = math.atan2(c2 - ey, c1 - ex)
            if arc_radius <= tool_radius:
                raise InterpError("tool radius not less than arc radius with comp")
        else:
            gamma = math.atan2(ey - c2, ex - c1)
            delta += math.pi
        nx, ny = ex + tool_radius * math.cos(gamma), ey + tool_radius * math.sin(gamma)
        small = TOLERANCE_CONCAVE_CORNER
        sweep = find_turn(opx, opy, c1, c2, turn, ex, ey)
        arc_kind = 3 if turn > 0 else 2
        centre = self.point(c1, c2, cz, (0, 0, 0))[:3]
        if beta < -small or beta > math.pi + small or (abs(beta - math.pi) < small and not inside(side, turn)):
            if not (self.queue and self.queue[0].kind in (2, 3)):
                cyy = arc_radius * math.sin(beta - math.pi / 2)
                if inside(side, turn):
                    dist = arc_radius - tool_radius
                    ratio = (cyy + tool_radius) / dist
                    if ratio > 1.0 or ratio < -1.0:
                        raise InterpError("arc move in concave corner cannot be reached by the tool without gouging")
                    angle = theta + math.asin(ratio) if turn > 0 else theta - math.asin(ratio)
                else:
                    dist = arc_radius + tool_radius
                    ratio = (cyy - tool_radius) / dist
                    if ratio > 1.0 or ratio < -1.0:
                        raise InterpError("arc move in concave corner cannot be reached by the tool without gouging")
                    angle = theta + math.pi - math.asin(ratio) if turn > 0 else theta + math.pi + math.asin(ratio)
                self.move_endpoint_and_flush(c1 + dist * math.cos(angle), c2 + dist * math.sin(angle))
            else:
                prev = self.queue[0]
                pc1, pc2 = prev.centre[u], prev.centre[w]
                oldrad = math.hypot(pc2 - prev.end[w], pc1 - prev.end[u])
                newrad = arc_radius - tool_radius if inside(side, turn) else arc_radius + tool_radius
                arc_cc = math.hypot(pc2 - c2, pc1 - c1)
                if oldrad == 0 or arc_cc == 0:
                    raise InterpError("arc to arc motion is invalid because the arcs have the same center")
                a = (oldrad ** 2 + arc_cc ** 2 - newrad ** 2) / (2 * oldrad * arc_cc)
                if a > 1.0 or a < -1.0:
                    raise InterpError("arc to arc motion makes a corner the compensated tool can't fit in without "
                                      "gouging")
                pullback = math.acos(a)
                cc_dir = math.atan2(c2 - pc2, c1 - pc1)
                if inside(side, prev.turn):
                    direction = cc_dir + pullback if turn > 0 else cc_dir - pullback
                else:
                    direction = cc_dir - pullback if turn > 0 else cc_dir + pullback
                self.move_endpoint_and_flush(pc1 + oldrad * math.cos(direction), pc2 + oldrad * math.sin(direction))
            self.hold(arc_kind, self.point(nx, ny, ez, end[3:]), centre=centre, turn=turn, sweep=sweep)
        elif beta > small:    # convex: an arc around the programmed corner, then the arc
            mx, my = opx + tool_radius * math.cos(delta), opy + tool_radius * math.sin(delta)
            self.dequeue()
            corner_turn = -1 if side == LEFT else 1
            self.hold(3 if corner_turn > 0 else 2, self.point(mx, my, cz, end[3:]),
                      centre=self.point(opx, opy, cz, (0, 0, 0))[:3], turn=corner_turn)
            self.dequeue()
            self.set_endpoint(mx, my)
            self.hold(arc_kind, self.point(nx, ny, ez, end[3:]), centre=centre, turn=turn, sweep=sweep)
        else:
            self.dequeue()
            self.set_endpoint(cx, cy)
            self.hold(arc_kind, self.point(nx, ny, ez, end[3:]), centre=centre, turn=turn, sweep=sweep)
        self.set_programmed(ex, ey, ez)
        self._moved_to(nx, ny, ez, end)
