"""Part programs for feedlog's LinuxCNC sample recordings (recordings/programs/*.ngc).

Each generator returns G-code text (RS274NGC, mm, absolute). The families exercise what the feed-rate
papers study: long and short segments with sharp and obtuse corners, a polygonal circle, a pocket of
zig-zag passes joined by arcs, a dense freeform patch of 0.05-0.5 mm segments, five-axis moves near
and away from the A = 0 singularity with different workpiece offsets. `shared_*` regenerate the test
programs of ../shared/linuxcnc (byte for byte) so their cycle times can be compared with the ones
measured there.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

HEADER = "G21 G90 G17 G94 G40 G49 G80"


def num(v: float) -> str:
    return f"{v:.4f}"


def move(x: float | None = None, y: float | None = None, z: float | None = None,
         a: float | None = None, c: float | None = None, *, g: str = "G1") -> str:
    words = [g]
    for letter, value in (("X", x), ("Y", y), ("Z", z), ("A", a), ("C", c)):
        if value is not None:
            words.append(f"{letter}{num(value)}")
    return " ".join(words)


def program(title: str, tolerance: str, feed: float, body: Iterable[str], *, start: str,
            end: str = "G0 Z5", prelude: Iterable[str] = ()) -> str:
    if any(ch in title for ch in "()"):
        raise ValueError(f"program title {title!r} would nest a comment")
    lines = ["%", f"({title})", HEADER, *prelude, tolerance, f"F{feed:g}", start, *body, end, "M2", "%"]
    return "\n".join(lines) + "\n"


# ---- 3-axis families -----------------------------------------------------------------------------

def corners(feed: float, tolerance: str, *, angles: tuple[float, ...] = (30, 60, 90, 120, 150),
            long_mm: float = 25.0, short_mm: float = 2.0) -> str:
    """A polyline turning by each corner angle in turn, alternating long and short segments.

    The interior angle between consecutive segments is `angle` (30 = sharp, 150 = obtuse).
    """
    x, y, heading = 0.0, 0.0, 0.0
    body = []
    for rep in range(2):
        for i, angle in enumerate(angles):
            for length in (long_mm, short_mm) if (i + rep) % 2 == 0 else (short_mm, long_mm):
                x += length * math.cos(math.radians(heading))
                y += length * math.sin(math.radians(heading))
                body.append(move(x, y))
                turn = 180.0 - angle
                heading += turn if len(body) % 2 else -turn
    return program(f"corners {','.join(f'{a:g}' for a in angles)} deg, segments {long_mm:g}/{short_mm:g} mm, "
                   f"F{feed:g}", tolerance, feed, body, start="G0 X0 Y0 Z0")


def polygon_circle(feed: float, tolerance: str, *, radius_mm: float = 25.0, sides: int = 90,
                   laps: int = 2) -> str:
    """A circle as a regular polygon, run `laps` times."""
    body = []
    for k in range(1, sides * laps + 1):
        t = 2 * math.pi * k / sides
        body.append(move(radius_mm * math.cos(t), radius_mm * math.sin(t)))
    return program(f"polygonal circle R{radius_mm:g}, {sides} sides, {laps} laps, F{feed:g}", tolerance, feed,
                   body, start=f"G0 X{num(radius_mm)} Y0 Z0")


def pocket(feed: float, tolerance: str, *, width_mm: float = 30.0, height_mm: float = 20.0,
           stepover_mm: float = 2.5) -> str:
    """Zig-zag passes along X joined by half-circle arcs (G2/G3) of radius stepover/2."""
    passes = int(round(height_mm / stepover_mm)) + 1
    r = stepover_mm / 2
    body = []
    for p in range(passes):
        y = p * stepover_mm
        x_end = width_mm if p % 2 == 0 else 0.0
        body.append(move(x_end, y))
        if p < passes - 1:
            arc = "G3" if p % 2 == 0 else "G2"
            body.append(f"{arc} X{num(x_end)} Y{num(y + stepover_mm)} I0 J{num(r)}")
    return program(f"pocket {width_mm:g}x{height_mm:g} mm, zig-zag stepover {stepover_mm:g} mm with arcs, "
                   f"F{feed:g}", tolerance, feed, body, start="G0 X0 Y0 Z0")


def freeform(feed: float, tolerance: str, *, width_mm: float = 16.0, rows: int = 5, row_step_mm: float = 2.0,
             amp_mm: float = 1.5, phase: float = 0.0) -> str:
    """Raster over z = amp sin(x/3 + phase) cos(y/4) with segment lengths sweeping 0.05-0.5 mm."""
    def z_at(x: float, y: float) -> float:
        return amp_mm * math.sin(x / 3.0 + phase) * math.cos(y / 4.0)

    body = []
    for r in range(rows):
        y = r * row_step_mm
        forward = r % 2 == 0
        s = 0.0
        while s < width_mm:
            # segment length varies smoothly along the row between 0.05 and 0.5 mm
            ds = 0.05 + 0.45 * (0.5 + 0.5 * math.sin(2 * math.pi * s / 5.0 + r))
            s = min(width_mm, s + ds)
            x = s if forward else width_mm - s
            body.append(move(x, y, z_at(x, y)))
        if r < rows - 1:
            x = width_mm if forward else 0.0
            body.append(move(x, y + row_step_mm, z_at(x, y + row_step_mm)))
    return program(f"freeform patch {width_mm:g}x{(rows - 1) * row_step_mm:g} mm, 0.05-0.5 mm segments, "
                   f"F{feed:g}", tolerance, feed, body, start=f"G0 X0 Y0 Z{num(z_at(0, 0))}")


# ---- five-axis families (xyzac-trt) --------------------------------------------------------------

def _offset_text(offset: tuple[float, float, float]) -> str:
    return " ".join(f"{k}{v:g}" for k, v in zip("XYZ", offset))


def _offset_prelude(offset: tuple[float, float, float]) -> list[str]:
    ox, oy, oz = offset
    return [f"G10 L2 P1 X{num(ox)} Y{num(oy)} Z{num(oz)} A0 C0", "G54"]


def five_axis_near(feed: float, tolerance: str, *, radius_mm: float = 20.0,
                   offset: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> str:
    """Near the singularity: a circle with A within +-2 deg while C turns a full revolution, then a
    straight pass whose tilt crosses A = 0."""
    body = []
    steps = 48
    for k in range(1, steps + 1):
        t = 2 * math.pi * k / steps
        body.append(move(radius_mm * math.cos(t), radius_mm * math.sin(t), 5.0 - 0.02 * k,
                         -2.0 * math.sin(t / 2), 360.0 * k / steps))
    for k in range(1, 21):
        f = k / 20
        body.append(move(radius_mm * (1 - 2 * f), 0.0, 4.04, -10.0 + 20.0 * f, 360.0))
    return program(f"five-axis near A=0: R{radius_mm:g} circle, A within +-2, C 0-360, A crossing 0; "
                   f"offset {_offset_text(offset)}, F{feed:g}", tolerance, feed, body, prelude=_offset_prelude(offset),
                   start=f"G0 X{num(radius_mm)} Y0 Z5 A0 C0", end="G0 Z20")


def five_axis_far(feed: float, tolerance: str, *, radius_mm: float = 20.0,
                  offset: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> str:
    """Away from the singularity: A between -45 and -25 deg along a circle while C turns, then a tilt
    sweep from A -30 to -60 and back."""
    body = []
    steps = 48
    for k in range(1, steps + 1):
        t = 2 * math.pi * k / steps
        body.append(move(radius_mm * math.cos(t), radius_mm * math.sin(t), 5.0 - 0.02 * k,
                         -35.0 - 10.0 * math.sin(t), 360.0 * k / steps))
    for k in range(1, 21):
        f = k / 20
        body.append(move(radius_mm, 10.0 * f, 4.04, -35.0 - 25.0 * math.sin(math.pi * f), 360.0 + 45.0 * f))
    return program(f"five-axis away from A=0: R{radius_mm:g} circle, A -45..-25, C 0-360, tilt sweep; "
                   f"offset {_offset_text(offset)}, F{feed:g}", tolerance, feed, body, prelude=_offset_prelude(offset),
                   start=f"G0 X{num(radius_mm)} Y0 Z5 A-35 C0", end="G0 Z20")


# ---- the test programs of ../shared/linuxcnc, regenerated ----------------------------------------

def shared_test(tolerance: str) -> str:
    """test_p001 / test_p01 / test_g61: 72-gon helix + zig-zag + 3D zig-zag at F3000."""
    lines = ["%", "(3-axis test: 72-gon helix + zig-zag + 3D zig-zag, F3000)", HEADER, tolerance, "F3000",
             "G0 X20 Y0 Z5", "G1 Z0"]
    for k in range(1, 73):
        t = 2 * math.pi * k / 72
        lines.append(move(20 * math.cos(t), 20 * math.sin(t), -0.01 * k))
    for k in range(1, 41):
        lines.append(move(20 + 2.5 * k, 2.5 if k % 2 else 0.0))
    for k in range(1, 41):
        lines.append(move(120 - k, 3.3 if k % 2 else 2.5, -0.72 if (k // 2) % 2 == 0 else -0.42))
    lines += ["G0 Z5", "M2", "%"]
    return "\n".join(lines) + "\n"


def shared_dense() -> str:
    """dense002q0: a R10 circle of 0.02 mm segments with G64 P0.01 Q0."""
    n = math.ceil(2 * math.pi * 10 / 0.02)
    lines = ["%", "(very dense circle 0.02mm segs)", "G21 G90 G17 G94", "G64 P0.01 Q0", "F3000", "G0 X10 Y0 Z0"]
    for k in range(1, n + 1):
        t = 2 * math.pi * k / n
        lines.append(move(10 * math.cos(t), 10 * math.sin(t)))
    lines += ["M2", "%"]
    return "\n".join(lines) + "\n"


def shared_5ax(tolerance: str) -> str:
    """5ax_p001 / 5ax_g61: R30 circle, Z 10 -> 5, A = -30 sin(theta/2), C 0 -> 360 at F3000."""
    lines = ["%", "(5-axis trt test)", HEADER, tolerance, "F3000", "G0 X30 Y0 Z20 A0 C0", "G1 Z10"]
    for k in range(1, 61):
        t = math.radians(6 * k)
        lines.append(move(30 * math.cos(t), 30 * math.sin(t), 10 - 5 * k / 60, -30 * math.sin(t / 2), 6.0 * k))
    lines += ["G0 Z30", "M2", "%"]
    return "\n".join(lines) + "\n"


Generator = Callable[[], str]


# ---- random CL-line training toolpaths (Chien et al. §2: dedicated training toolpaths) ------------

def _segment_length(rng, feed: float) -> float:
    """A segment length from a mix of long lines, medium lines and short CL steps.

    At high feed short steps stay >= 0.3 mm so LinuxCNC's per-block feed limit (a block takes at least
    about one servo period) never sets the speed: under host load that limit is not repeatable.
    """
    shortest = 0.3 if feed > 1500 else 0.05
    u = rng.random()
    if u < 0.2:
        return rng.uniform(5.0, 25.0)
    if u < 0.5:
        return rng.uniform(1.0, 5.0)
    return math.exp(rng.uniform(math.log(shortest), math.log(1.0)))


def random_cl(feed: float, tolerance: str, *, seed: int, blocks: int, five_axis: bool = False,
              box_mm: float = 40.0) -> str:
    """Random CL-line toolpath: runs of equal segments (curves, turning a little at each point) and
    single lines, with corner angles from 0 to 170 deg between runs, gentle Z changes; in five-axis
    mode A (-55..0 deg) and C also move by a few degrees per block.

    Deterministic for a given `seed`. Stays within +-`box_mm` of the origin (headings turn back at the
    walls).
    """
    import random

    rng = random.Random(seed)
    x = y = 0.0
    z = 0.0
    a, c = -20.0, 0.0
    heading = rng.uniform(0, 360)
    body: list[str] = []
    while len(body) < blocks:
        run_len = rng.choice((1, 1, 1, 3, 6, 12, 24))
        seg = _segment_length(rng, feed)
        if run_len > 1:
            seg = min(seg, 3.0)
        bend = rng.uniform(-20.0, 20.0) if run_len > 1 else 0.0  # per-point turn inside a run
        # a corner between runs: the path turns by 180 - interior angle
        heading += rng.choice((-1, 1)) * rng.uniform(10.0, 180.0)
        dz = rng.uniform(-0.05, 0.05)
        da = rng.uniform(-3.0, 3.0) if five_axis else 0.0
        dc = rng.uniform(-6.0, 6.0) if five_axis else 0.0
        for _ in range(min(run_len, blocks - len(body))):
            nx = x + seg * math.cos(math.radians(heading))
            ny = y + seg * math.sin(math.radians(heading))
            if abs(nx) > box_mm or abs(ny) > box_mm:
                heading = math.degrees(math.atan2(-y, -x)) + rng.uniform(-60, 60)
                nx = x + seg * math.cos(math.radians(heading))
                ny = y + seg * math.sin(math.radians(heading))
            x, y = nx, ny
            z = min(5.0, max(-5.0, z + dz * seg))
            if five_axis:
                a = min(0.0, max(-55.0, a + da))
                c += dc
                body.append(move(x, y, z, a, c))
            else:
                body.append(move(x, y, z))
            heading += bend
    kind = "five-axis" if five_axis else "3-axis"
    start = f"G0 X0 Y0 Z0 A{num(-20.0)} C0" if five_axis else "G0 X0 Y0 Z0"
    return program(f"random CL-line toolpath {kind}, seed {seed}, {blocks} blocks, F{feed:g}", tolerance, feed,
                   body, start=start, end="G0 Z20" if five_axis else "G0 Z5")


# ---- Chien-style mixed random toolpaths: short programs over every regime of the held-out tests ----

TOLERANCES = ("G61", "G64 P0.01", "G64 P0.05", "G64 P0.1")
FEEDS = (1000.0, 1500.0, 2000.0, 2500.0, 3000.0)


def mix_settings(seed: int, *, five_axis: bool) -> dict:
    """Feed, tolerance, Q0, CL-line count and work offset of `random_mix` program `seed`."""
    import random

    rng = random.Random(10_000 + seed)
    tolerance = rng.choice(TOLERANCES)
    q0 = tolerance != "G61" and rng.random() < 0.4
    offset = (0.0, 0.0, 0.0)
    if five_axis and rng.random() < 0.4:
        offset = (round(rng.uniform(-15, 15), 1), round(rng.uniform(-15, 15), 1), round(rng.uniform(-5, 5), 1))
    return {"feed": rng.choice(FEEDS), "tolerance": tolerance + (" Q0" if q0 else ""),
            "lines": rng.randint(60, 200 if five_axis else 300), "offset": offset}


def random_mix(feed: float, tolerance: str, *, seed: int, lines: int, five_axis: bool = False,
               offset: tuple[float, float, float] = (0.0, 0.0, 0.0), box_mm: float = 30.0,
               min_time_s: float = 2.0, weights: tuple[int, int, int, int] = (2, 3, 3, 2),
               dense_count: tuple[int, int] = (20, 80)) -> str:
    """A short random CL-line toolpath (Chien et al. §2) made of pieces drawn at random until `lines`
    CL lines: a long line (5-30 mm) after a sharp (interior 10-60 deg) or obtuse (120-175 deg) corner;
    a few medium lines (1-8 mm) with random corners; a curved run of short segments (0.1-1 mm, radius
    2-20 mm, like a polygonal circle); a dense curved run (0.02-0.06 mm: at F1000-F3000 LinuxCNC's
    per-block rate sets the speed). In five-axis mode each piece also moves A (toward a target in
    -55..0, a third of them within 2 deg of the A = 0 singularity) and turns C (up to 180 deg over a
    piece, at most 1.5 and 4 deg per mm of the piece). A long line comes whenever the path so far is
    shorter than its share of `min_time_s` at `feed`, so that even a dense program moves for a while.
    `weights`: how often a long line, medium lines, a short run and a dense run are drawn;
    `dense_count`: the range of a dense run's segment count.
    Deterministic for a given `seed`; stays within +-`box_mm` in X and Y and 0..6 mm in Z.
    """
    import random

    rng = random.Random(seed)
    x = y = 0.0
    z = 2.0
    a, c = -20.0, 0.0
    heading = rng.uniform(0.0, 360.0)
    body: list[str] = []

    def emit(nx: float, ny: float, nz: float, na: float, nc: float) -> None:
        body.append(move(nx, ny, nz, na, nc) if five_axis else move(nx, ny, nz))

    path_mm = 0.0
    want_mm = min_time_s * feed / 60.0  # at least min_time_s of CAM time: long lines when behind
    while len(body) < lines or path_mm < want_mm:
        kind = rng.choices(("long", "corners", "short_run", "dense_run"), weights=weights)[0]
        if path_mm < want_mm * min(1.0, len(body) / lines):
            kind = "long"
        if kind == "long":
            sharp = rng.random() < 0.5
            turn = 180.0 - (rng.uniform(10, 60) if sharp else rng.uniform(120, 175))
            steps = [(rng.uniform(5.0, 30.0), rng.choice((-1, 1)) * turn)]
        elif kind == "corners":
            steps = [(rng.uniform(1.0, 8.0), rng.choice((-1, 1)) * rng.uniform(5.0, 170.0))
                     for _ in range(rng.randint(2, 6))]
        else:
            dense = kind == "dense_run"
            seg = rng.uniform(0.02, 0.06) if dense else rng.uniform(0.1, 1.0)
            radius = rng.uniform(1.0, 10.0) if dense else rng.uniform(2.0, 20.0)
            count = rng.randint(*dense_count) if dense else rng.randint(5, 40)
            bend = rng.choice((-1, 1)) * math.degrees(seg / radius)
            first_turn = rng.choice((-1, 1)) * rng.uniform(0.0, 90.0)
            steps = [(seg, first_turn if k == 0 else bend) for k in range(count)]
        steps = steps[:max(1, lines - len(body))]
        dz = rng.uniform(-0.3, 0.3)
        if five_axis:  # rotary moves of at most 1.5 deg (A) and 4 deg (C) per mm of the piece's path
            piece_mm = sum(length for length, _ in steps)
            target_a = rng.uniform(-2.0, 0.0) if rng.random() < 1 / 3 else rng.uniform(-55.0, -5.0)
            target_a = a + max(-1.5 * piece_mm, min(1.5 * piece_mm, target_a - a))
            turn_c = rng.choice((-1, 1)) * rng.uniform(0.0, min(180.0, 4.0 * piece_mm)) if rng.random() < 0.6 else 0.0
        for k, (length, turn) in enumerate(steps):
            heading += turn
            nx = x + length * math.cos(math.radians(heading))
            ny = y + length * math.sin(math.radians(heading))
            if abs(nx) > box_mm or abs(ny) > box_mm:  # turn back toward the middle
                heading = math.degrees(math.atan2(-y, -x)) + rng.uniform(-45.0, 45.0)
                nx = x + length * math.cos(math.radians(heading))
                ny = y + length * math.sin(math.radians(heading))
            x, y = nx, ny
            path_mm += length
            z = min(6.0, max(0.0, z + dz * min(length, 1.0) / len(steps)))
            if five_axis:
                f = (k + 1) / len(steps)
                na = a + (target_a - a) * f
                emit(x, y, z, na, c + turn_c * f)
            else:
                emit(x, y, z, a, c)
        if five_axis:
            a, c = target_a, c + turn_c
    kind = "five-axis" if five_axis else "3-axis"
    start = f"G0 X0 Y0 Z2 A{num(-20.0)} C0" if five_axis else "G0 X0 Y0 Z2"
    prelude = _offset_prelude(offset) if any(offset) else []
    return program(f"random mixed toolpath {kind}, seed {seed}, {len(body)} CL lines, F{feed:g}, "
                   f"offset {_offset_text(offset)}", tolerance, feed, body, prelude=prelude, start=start,
                   end="G0 Z20" if five_axis else "G0 Z8")
