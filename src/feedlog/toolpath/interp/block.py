"""A line's words evaluated into a `Block`: G codes by modal group, M codes, one value per letter,
the motion it will make, and LinuxCNC's checks on which words belong together."""

from __future__ import annotations

import math

from feedlog.toolpath.interp.codes import CYCLES, G_GROUP, M_GROUP, REFUSED_G, g_name
from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.expr import as_int
from feedlog.toolpath.limits import MAX_WORD, sci

AXIS_LETTERS = "xyzabc"
_AXES_OR_POLAR = "xyzabc@^"
_COVET_AXES = (100, 280, 300, 520, 920)  # group-0 codes that take axis words


class Block:
    """`g`: group -> code x10; `m`: group -> M number; `v`: letter -> value (x, y, f, p, ...);
    `motion`: the motion code this block executes (-1: none)."""

    __slots__ = ("g", "m", "v", "motion", "m_list")

    def __init__(self) -> None:
        self.g: dict[str, int] = {}
        self.m: dict[str, int] = {}
        self.v: dict[str, float] = {}
        self.motion = -1
        self.m_list: list[int] = []


def build(words, C, unknown_u: bool = True) -> Block:
    """Evaluate a line's words (letter, float or function) into a Block, with LinuxCNC's read checks."""
    b = Block()
    g, m, v = b.g, b.m, b.v
    for letter, raw in words:
        value = raw(C) if callable(raw) else raw
        if letter == "g":
            x10 = value * 10.0
            code = math.floor(x10)
            if x10 - code > 0.999:
                code = math.ceil(x10)
            elif x10 - code > 0.001:
                raise InterpError(f"G code out of range (G{value:g})")
            code = int(code)
            if code < 0:
                raise InterpError("negative G code used")
            group = G_GROUP.get(code)
            if group is None:
                raise InterpError(f"unknown G code used ({g_name(code)})")
            if group in g and not (code == 800 or g[group] == 800):
                raise InterpError(f"two G codes used from the same modal group ({g_name(g[group])} {g_name(code)})")
            if not (code == 800 and group in g):
                g[group] = code
        elif letter == "m":
            code = as_int(value, "M code")
            if code < 0:
                raise InterpError("negative M code used")
            if code == 98:
                raise InterpError("M98 must begin its line (after an optional N number), as LinuxCNC reads "
                                  "Fanuc-style subprogram calls")
            if code == 99:    # not at the start of a line: an M code of the stop group (the main program's end)
                if "stop" in m:
                    raise InterpError(f"two M codes used from the same modal group (M{m['stop']} M99)")
                m["stop"] = 99
                b.m_list.append(99)
                continue
            if code > 199:
                raise InterpError(f"M code greater than 199 (M{code})")
            group = M_GROUP.get(code)
            if group is None:
                raise InterpError(f"unknown M code used (M{code})")
            if group in m:
                raise InterpError(f"two M codes used from the same modal group (M{m[group]} M{code})")
            m[group] = code
            b.m_list.append(code)
        else:
            if letter in v:
                raise InterpError(f"multiple {letter.upper()} words on one line")
            if letter in "uvw":
                raise InterpError(f"{letter.upper()} axis words are not supported (feedlog reads X Y Z A B C machines)")
            if letter in "tlh" or letter == "d":
                if letter == "t":
                    value = float(as_int(value, "T word"))
                    if value < 0:
                        raise InterpError("negative tool id used")
                elif letter == "l":
                    value = float(as_int(value, "L word"))
                    if value < 0:
                        raise InterpError("negative L word used")
                elif letter == "h":
                    value = float(as_int(value, "H word"))
                    if value < -1:
                        raise InterpError("negative H word used")
            if abs(value) > MAX_WORD:   # feedlog's bound on every number (toolpath.limits), LinuxCNC has none
                raise InterpError(f"number out of range (beyond +-{sci(MAX_WORD)}): {letter.upper()}{value:.4g}")
            if letter == "f" and value < 0.0:
                raise InterpError("negative F word used")
            elif letter == "s" and value < 0.0:
                raise InterpError("negative spindle speed used")
            v[letter] = value
    return b


def refuse(b: Block) -> None:
    """Codes whose motion feedlog does not simulate: refused before any other check of the line."""
    for code in b.g.values():
        why = REFUSED_G.get(code)
        if why is not None:
            raise InterpError(why)


def enhance(b: Block, motion_mode: int, plane: int) -> None:
    """Which motion the block makes (LinuxCNC's enhance_block) and the word checks (check_items)."""
    v, g = b.v, b.g
    polar = "@" in v or "^" in v
    if polar:
        if plane != 170:
            raise InterpError("cannot use polar coordinates except in the G17 plane")
        if "x" in v:
            raise InterpError("cannot specify both polar coordinate and X word")
        if "y" in v:
            raise InterpError("cannot specify both polar coordinate and Y word")
    axis = any(a in v for a in AXIS_LETTERS)
    ijk = "i" in v or "j" in v or "k" in v
    mode0 = g.get("nonmodal", -1)
    mode1 = g.get("motion", -1)
    covets = mode0 in _COVET_AXES
    if mode1 != -1:
        if mode1 == 800:
            if (polar or axis) and not covets:
                raise InterpError("cannot use axis values with G80")
            if not axis and mode0 in (520, 920):
                raise InterpError("all axes missing with G52 or G92")
        else:
            if covets:
                raise InterpError("cannot use two G codes that both use axis values")
            if not axis and not polar and mode1 not in (0, 10, 20, 30, 52):
                raise InterpError(f"all axes missing with motion code {g_name(mode1)}")
        b.motion = mode1
    elif covets:
        if polar and mode0 == 920:
            raise InterpError("polar coordinates can only be used for motion")
        if not axis and mode0 in (520, 920):
            raise InterpError("all axes missing with G52 or G92")
    elif axis or polar:
        tl = g.get("tool_length", -1)
        if motion_mode in (-1, 800) and tl not in (431, 432):
            raise InterpError("cannot use axis values without a G code that uses them")
        if tl != 431:
            b.motion = motion_mode
    elif ijk and motion_mode in (20, 30):
        b.motion = motion_mode
    if polar and b.motion == -1:
        raise InterpError("polar coordinates can only be used for motion")
    _check(b)


def _check(b: Block) -> None:
    v, g, m = b.v, b.g, b.m
    motion = b.motion
    mode0 = g.get("nonmodal", -1)
    if mode0 == 40:
        if "p" not in v:
            raise InterpError("dwell time missing with G4")
        if motion in (20, 30):
            raise InterpError("G4 not allowed with G2 or G3 because they both use P")
    elif mode0 == 100:
        p = v.get("p", -1.0)
        lw = v.get("l", -1.0)
        if lw not in (0, 1, 2, 10, 11, 20):
            raise InterpError("line with G10 does not have L0, L1, L10, L11, L2, or L20")
        p_int = int(p + 0.5) if p >= 0 else int(p - 0.5)
        if (p + 0.0001) - p_int > 0.0002:
            raise InterpError("P value not an integer with G10")
        if lw in (2, 20) and not 0 <= p_int <= 9:
            raise InterpError(f"P value out of range (0-9) with G10 L{int(lw)}")
        if lw in (1, 10, 11) and p_int < 1:
            raise InterpError(f"P value out of range with G10 L{int(lw)}")
    elif mode0 == 530:
        if motion not in (0, 10):
            raise InterpError("must use G0 or G1 with G53")
    cycle = motion in CYCLES
    for a in "abc":
        if a in v and cycle:
            raise InterpError(f"cannot put an {a.upper()} in a canned cycle")
    if "e" in v and m.get("io") not in (66, 67, 68):
        raise InterpError("E word with no G76, M66, M67 or M68 to use it")
    if "d" in v and g.get("comp", -1) not in (410, 420, 411, 421) and g.get("spindle_mode", -1) != 960:
        raise InterpError("D word with no G41, G41.1, G42, G42.1 or G96 to use it")
    if "h" in v and g.get("tool_length", -1) not in (430, 432):
        raise InterpError("H word with no G43 or G43.2 to use it")
    if "i" in v and motion not in (20, 30, 50, 51, 870) and mode0 != 100:
        raise InterpError("I word with no G2, G3, G5, G5.1, G10 or G87 to use it")
    if "j" in v and motion not in (20, 30, 50, 51, 870) and mode0 != 100:
        raise InterpError("J word with no G2, G3, G5, G5.1, G10 or G87 to use it")
    if "k" in v and motion not in (20, 30, 870):
        raise InterpError("K word with no G2, G3 or G87 to use it")
    if "l" in v and not (810 <= motion <= 890 or motion in (730, 52)) and mode0 != 100 \
            and g.get("comp", -1) not in (410, 411, 420, 421) and m.get("io") != 66:
        raise InterpError("L word with no G10, cutter compensation, canned cycle, G5.2 or M66 to use it")
    if "p" in v:
        user_m = any(c >= 100 for c in b.m_list)
        if (mode0 not in (100, 40) and g.get("control") != 640 and motion not in (820, 860, 880, 890, 20, 30, 50, 52, 740, 840)
                and m.get("override") not in (50, 51, 52, 53) and m.get("io") not in (62, 63, 64, 65, 66)
                and m.get("spindle") != 19 and not user_m):
            raise InterpError("P word with no G2 G3 G4 G5 G5.2 G10 G64 G82 G86 G88 G89 or M50-M53 M62-M66 to use it")
        if motion in (20, 30):
            p = v["p"]
            if abs(round(p) - p) > 0.001:
                raise InterpError("P value not an integer with G2 or G3")
            if round(p) < 1:
                raise InterpError("P value should be 1 or greater with G2 or G3")
    if "q" in v and motion not in (830, 730, 50) and m.get("io") not in (66, 67, 68) and mode0 != 100 \
            and g.get("control") != 640 and m.get("toolchange") != 61 and not any(c >= 100 for c in b.m_list):
        raise InterpError("Q word with no G5, G10, G64, G73, G83, M66, M67, M68 or user M code that uses it")
    if "r" in v and motion not in (20, 30, 730, 740) and not 810 <= motion <= 890 and mode0 != 100 \
            and m.get("spindle") != 19:
        raise InterpError("R word with no G code that uses it")
    if g.get("spindle_mode") == 960 and "s" not in v:
        raise InterpError("S word missing with G96")
