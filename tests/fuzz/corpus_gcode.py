"""Fuzz cases for part programs: `feedlog program --json` and `feedlog sim --json` on mutated G-code.

Seeds are the example programs and some bundled session programs; mutations are the generic text
damage (mutate.py) plus the number classes that once overflowed: 320-digit coordinates, tiny feeds,
huge dwells, 400-digit N words, rotary words for a three-axis machine, arc turn counts past int16,
incremental moves summed past float64, inch values scaled past it.
"""

from __future__ import annotations

import random

from tests.fuzz import mutate
from tests.fuzz.cases import EXAMPLES, PROGRAMS, Case, Run

SEEDS = {  # file -> profile
    EXAMPLES / "pocket.ngc": "linuxcnc-xyz",
    EXAMPLES / "arcs_g18_g19.ngc": "linuxcnc-xyz",
    EXAMPLES / "work_offsets.ngc": "linuxcnc-xyz",
    EXAMPLES / "fiveaxis_ac.ngc": "linuxcnc-xyzac",
    PROGRAMS / "corners_f1000_p01.ngc": "linuxcnc-xyz",
    PROGRAMS / "circle_f1000_p01.ngc": "linuxcnc-xyz",
    PROGRAMS / "5ax_g61.ngc": "linuxcnc-xyzac",
}
NAME = "t.ngc"
BIG = mutate.HUGE_DIGITS


def _runs(profile: str, expect: str = "any", *, same: bool = False) -> list[Run]:
    return [Run(["program", NAME, "--json", "--profile", profile], expect, same_as_seed=same),
            Run(["sim", NAME, "--json", "--profile", profile], expect, same_as_seed=same)]


def _case(name: str, text: bytes | str, profile: str = "linuxcnc-xyz", expect: str = "any", *,
          seed: bytes | None = None) -> Case:
    data = text.encode() if isinstance(text, str) else text
    return Case("gcode", f"gcode/{name}", {NAME: data}, _runs(profile, expect, same=seed is not None), NAME,
                seed={NAME: seed} if seed is not None else {})


def targeted() -> list[Case]:
    """The number classes named in issue #19, each on its own, plus neighbours of each."""
    head = "G21 G90 G17 G94\nG0 X0 Y0 Z1\n"
    programs = {
        "x-320-digits": f"{head}G1 X{BIG} F100\n",
        "x-320-digit-fraction": f"{head}G1 X0.{BIG}1 F100\n",
        "x-e400-is-e-word": f"{head}G1 X1e400 F100\n",
        "x-1e300-length-overflow": f"{head}G1 X1{'0' * 300} Y-1{'0' * 300} F100\n",
        "feed-1e-12": f"{head}G1 X10 F0.000000000001\n",
        "feed-1e-9-long-program": head + "".join(f"G1 X{k % 2 * 10} F0.000000001\n" for k in range(50)),
        "feed-negative": f"{head}G1 X10 F-100\n",
        "feed-zero": f"{head}G1 X10 F0\n",
        "dwell-1e12": f"{head}G4 P1000000000000\n",
        "dwell-1e9-repeated": head + "G4 P999999999\n" * 20,
        "dwell-negative": f"{head}G4 P-1\n",
        "n-word-400-digits": f"{head}N{'9' * 400} G1 X1 F100\n",
        "n-word-20-digits": f"{head}N{'9' * 20} G1 X1 F100\n",
        "n-word-fraction": f"{head}N1.5 G1 X1 F100\n",
        "a-word-on-xyz": f"{head}G1 X1 A10 F100\n",
        "c-word-on-xyz": f"{head}G1 X1 C-90 F100\n",
        "arc-p-40000": f"{head}G2 X10 Y0 I5 J0 P40000 F100\n",
        "arc-p-32768": f"{head}G2 X10 Y0 I5 J0 P32768 F100\n",
        "arc-p-huge": f"{head}G2 X10 Y0 I5 J0 P1{'0' * 30} F100\n",
        "arc-r-tiny": f"{head}G2 X10 Y0 R0.0001 F100\n",
        "arc-i-huge": f"{head}G2 X10 Y0 I1{'0' * 200} J0 F100\n",
        "g91-overflow": head + "G91 G1 F100\n" + f"X9{'9' * 306}\n" * 6,
        "g91-1e8-steps": head + "G91 G1 F6000\n" + "X100000000\n" * 30,
        "g20-huge": f"{head}G20 G1 X9{'9' * 306} F100\n",
        "g20-1e300": f"{head}G20 G1 X1{'0' * 300} F100\n",
        "g93-tiny": f"{head}G93 G1 X10 F0.000000000001\n",
        "g93-huge": f"{head}G93 G1 X10 F1{'0' * 300}\n",
        "g64-p-huge": f"{head}G64 P1{'0' * 300}\nG1 X10 F100\nY10\n",
        "spindle-huge": f"{head}S{BIG} M3\nG1 X10 F100\n",
        "g10-huge-offset": f"{head}G10 L2 P1 X{BIG}\nG54 G1 X1 F100\n",
        "g92-huge": f"{head}G92 X1{'0' * 300}\nG1 X1 F100\n",
        "rapid-far": f"{head}G0 X1{'0' * 15}\n",
        "ijk-zero-orientation": f"{head}G1 X1 I0 J0 K0 F100\n",
    }
    # 0.999... (320 nines) is a number near 1; an inverse-time feed below 0.1 units/min is raised to it (LinuxCNC)
    fine = {"n-word-fraction": "any", "x-320-digit-fraction": "ok", "g93-tiny": "ok"}
    cases = [_case(name, text, expect=fine.get(name, "error")) for name, text in programs.items()]
    cases[[c.name for c in cases].index("gcode/x-e400-is-e-word")].runs[0].expect = "error"
    return cases


def damaged(rng: random.Random) -> list[Case]:
    """Generic damage to every seed: line endings, BOM, encodings, truncation, flips, swaps."""
    cases = []
    for path, profile in SEEDS.items():
        data = path.read_bytes()
        stem = path.stem
        cases += [
            _case(f"{stem}/cr-only", mutate.line_endings(data, b"\r"), profile, seed=data),
            _case(f"{stem}/crlf", mutate.line_endings(data, b"\r\n"), profile, seed=data),
            _case(f"{stem}/mixed-endings", mutate.mixed_endings(data, rng), profile, seed=data),
            _case(f"{stem}/bom", mutate.BOM + data, profile, seed=data),
            _case(f"{stem}/utf16", mutate.reencode(data, "utf-16"), profile, "error"),
            _case(f"{stem}/nul-byte", mutate.insert_line(data, rng, b"G1 X1\x00 F100"), profile, "error"),
            _case(f"{stem}/truncated-a", mutate.truncate(data, rng), profile),
            _case(f"{stem}/truncated-b", mutate.truncate(data, rng), profile),
            _case(f"{stem}/bitflip-a", mutate.flip_bits(data, rng), profile),
            _case(f"{stem}/bitflip-b", mutate.flip_bits(data, rng, count=3), profile),
            _case(f"{stem}/swapped-lines", mutate.swap_lines(data, rng), profile),
            _case(f"{stem}/repeated-line", mutate.repeat_line(data, rng, times=5), profile),
            _case(f"{stem}/inserted-bytes", mutate.insert_bytes(data, rng), profile),
        ]
    return cases


def odd_files(rng: random.Random) -> list[Case]:
    """Empty, comment-only, unbalanced, latin-1, and huge files (good and bad)."""
    good = "".join(f"G1 X{k % 100} Y{(k * 7) % 50} F{1000 + k % 7}\n" for k in range(100_000))
    return [
        _case("empty", b""),
        _case("only-percent", "%\n%\n"),
        _case("only-comments", "(a)\n;b\n(c) (d)\n"),
        _case("unbalanced-paren", "G1 X1 (open\nG1 X2 F100\n", expect="error"),
        _case("nested-comment", "G1 X1 (a (b) c) F100\n", expect="error"),
        _case("latin1-comment", "G21 (Fr\xe4se \xd8 6)\nG1 X1 F100\n".encode("latin-1"), expect="ok"),
        _case("long-line-1mb", "(" + "x" * 1_000_000 + ")\nG1 X1 F100\n", expect="ok"),
        _case("100k-good-lines", good, expect="ok"),
        _case("100k-bad-lines", "G1 X1 Q\n" * 100_000, expect="error"),
        _case("100k-lines-last-bad", good + "G1 X1 #5\n", expect="error"),
        _case("random-bytes", bytes(rng.randrange(256) for _ in range(4096))),
        _case("parameters", "#1=5\nG1 X#1 F100\nM2\n", expect="ok"),        # the interpreter reads them
        _case("undefined-parameter", "G1 X#<nope> F100\nM2\n", expect="error"),
    ]


def build(rng: random.Random) -> list[Case]:
    return targeted() + damaged(rng) + odd_files(rng)
