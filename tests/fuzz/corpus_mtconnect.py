"""Fuzz cases for MTConnect imports: `feedlog import FILE.txt|FILE.xml -o out.mcap` (strict and --lenient).

Seeds are the committed real-shaped fixtures: the Hurco-like SHDR log (inches, in/min declared) and the
Mazak-like Streams XML (three saved responses), and the real NIST test bed logs (tests/fixtures/ingest/nist:
the Hurco box op 2 Split SHDR with its program attached, the Mazak day's first lines), imported with no
options. Mutations: truncation, bit flips, inserted and deleted bytes, NaN/inf/huge values, bad
timestamps, CR/CRLF/mixed line ends, a BOM, UTF-16 and Latin-1, swapped and repeated lines, a DOCTYPE
with entities, an MTConnectError document, empty files.
"""

from __future__ import annotations

import random

from tests.fuzz import mutate
from tests.fuzz.cases import FIXTURES, Case, Run

REAL = FIXTURES / "real"
NIST = FIXTURES / "nist"   # real public-domain logs (NIST SMS test bed)
SHDR_UNITS = ("--length-unit", "in", "--feed-unit", "in/min")


def _case(name: str, file: str, data: bytes, expect: str = "any", *, lenient: str | None = None,
          seed: bytes | None = None, extra: tuple[str, ...] = ()) -> Case:
    argv = ["import", file, *extra, "-o", "out.mcap"]
    runs = [Run(argv, expect, same_as_seed=seed is not None)]
    if lenient is not None:
        runs.append(Run(argv + ["--lenient"], lenient))
    return Case("mtconnect", f"mtconnect/{name}", {file: data}, runs, file,
                seed={file: seed} if seed is not None else {})


def _shdr_value(data: bytes, rng: random.Random, key: bytes, value: bytes) -> bytes:
    """One observation of `key` (on a random line holding it) given `value`."""
    lines = mutate.lines_of(data)
    holding = [i for i, line in enumerate(lines) if b"|" + key + b"|" in line and b"UNAVAILABLE" not in line]
    i = rng.choice(holding)
    fields = lines[i].split(b"|")
    fields[fields.index(key) + 1] = value
    lines[i] = b"|".join(fields)
    return b"\n".join(lines)


def _damaged(case, data: bytes, rng: random.Random, *, cuts: int, edits: int) -> list[Case]:
    """Random damage: `cuts` truncations and bit-flip runs, `edits` inserted and deleted byte runs."""
    out = []
    for k in range(cuts):
        out.append(case(f"truncated-{k}", mutate.truncate(data, rng), lenient="any"))
        out.append(case(f"bitflip-{k}", mutate.flip_bits(data, rng, count=1 + k), lenient="any"))
    for k in range(edits):
        out.append(case(f"inserted-{k}", mutate.insert_bytes(data, rng), lenient="any"))
        out.append(case(f"deleted-{k}", mutate.delete_bytes(data, rng), lenient="any"))
    return out


def _shdr(rng: random.Random) -> list[Case]:
    data = (REAL / "hurco_shdr.txt").read_bytes()
    f = "h.txt"

    def case(name, mutated, expect="any", **kw):
        return _case(f"shdr/{name}", f, mutated, expect, extra=SHDR_UNITS, **kw)

    cases = [case(f"value-{v.decode() or 'empty'}", _shdr_value(data, rng, b"Xact", v), "error", lenient="ok")
             for v in (b"nan", b"inf", b"-inf", b"1e400", b"abc", b"")]
    cases += [case(f"stamp-{label}", _shdr_value(data, rng, b"Xact", b"1").replace(b"2018-06-05T14:03:12", stamp, 1),
                   "error", lenient="ok")
              for label, stamp in (("text", b"yesterday"), ("year-99999", b"99999-06-05T14:03:12"),
                                   ("month-13", b"2018-13-05T14:03:12"))]
    cases += [
        case("line-feed-nan", _shdr_value(data, rng, b"path_feedrate", b"NaN"), "error", lenient="ok"),
        case("line-number-fraction", _shdr_value(data, rng, b"line", b"12.5"), "error", lenient="ok"),
        case("line-number-huge", _shdr_value(data, rng, b"line", b"9" * 30), "error", lenient="ok"),
        case("crlf", mutate.line_endings(data, b"\r\n"), seed=data),
        case("cr-only", mutate.line_endings(data, b"\r"), seed=data),
        case("mixed-endings", mutate.mixed_endings(data, rng), seed=data),
        case("bom", mutate.BOM + data, seed=data),
        case("utf16", mutate.reencode(data, "utf-16"), "error"),
        case("latin1-message", data.replace(b"Program O2101 loaded", "Programm geladen \xb5".encode("latin-1")),
             "error"),
        case("nul-byte", data.replace(b"Hurco01", b"Hur\x00co01", 1), "error"),
        case("empty", b"", "error"),
        case("commands-only", b"* shdrVersion: 2.0\n* device: x\n", "error"),
        case("all-unavailable", b"2018-06-05T14:03:09Z|Xact|UNAVAILABLE|Yact|UNAVAILABLE|Zact|UNAVAILABLE\n", "error"),
        case("no-mapped-key", b"2018-06-05T14:03:09Z|Q|1\n2018-06-05T14:03:10Z|Q|2\n", "error"),
        case("swapped-lines", mutate.swap_lines(data, rng, first=6), lenient="any"),
        case("repeated-line", mutate.repeat_line(data, rng, first=6), lenient="any"),
        case("dropped-lines", mutate.drop_lines(data, rng, first=6), lenient="any"),
        case("two-devices", data.replace(b"|Xact|", b"|a:Xact|", 3).replace(b"|Yact|", b"|b:Yact|", 3), "error"),
        case("condition-on-mapped-key", data + b"2018-06-05T14:03:30Z|Xact|FAULT|1|2|HIGH|servo\n", "error",
             lenient="ok"),
    ]
    return cases + _damaged(case, data, rng, cuts=8, edits=3)


def _xml(rng: random.Random) -> list[Case]:
    data = (REAL / "mazak_streams.xml").read_bytes()
    f = "m.xml"

    def case(name, mutated, expect="any", **kw):
        return _case(f"xml/{name}", f, mutated, expect, **kw)

    def value(v: bytes) -> bytes:
        marker = b'subType="ACTUAL">'
        starts = [i for i in range(len(data)) if data.startswith(marker, i)]
        k = rng.choice(starts) + len(marker)
        return data[:k] + v + data[data.index(b"<", k):]

    cases = [case(f"value-{v.decode() or 'empty'}", value(v), "error", lenient="ok")
             for v in (b"nan", b"inf", b"1e400", b"abc", b"")]
    cases += [
        case("stamp-text", data.replace(b'timestamp="2019-02-11T09:30:1', b'timestamp="later', 1), "error",
             lenient="ok"),
        case("crlf", mutate.line_endings(data, b"\r\n"), seed=data),
        case("cr-only", mutate.line_endings(data, b"\r"), seed=data),
        case("bom", mutate.BOM + data, seed=data),
        case("utf16", mutate.reencode(data, "utf-16"), "error"),
        case("doctype", data.replace(b"<MTConnectStreams", b'<!DOCTYPE x [<!ENTITY a "aaaa">]><MTConnectStreams', 1),
             "error"),
        case("error-document", b'<?xml version="1.0"?><MTConnectError><Errors><Error errorCode="OUT_OF_RANGE">'
                               b"from is out of range</Error></Errors></MTConnectError>", "error"),
        case("not-streams", b'<?xml version="1.0"?><MTConnectDevices><Devices/></MTConnectDevices>', "error"),
        case("empty", b"", "error"),
        case("no-observations", data[:data.index(b"<Streams>")] + b"<Streams/></MTConnectStreams>", "error"),
        case("text-before", b"HTTP/1.1 200 OK\n\n" + data, "error"),
        case("unclosed", data[:data.rindex(b"</MTConnectStreams>")], "error"),
    ]
    return cases + _damaged(case, data, rng, cuts=6, edits=2)


def _nist(rng: random.Random) -> list[Case]:
    """The real logs, no options (the default preset must find their names), the program attached."""
    hurco = (NIST / "Box-OP2-Hurco02-01of20.txt").read_bytes()
    mazak = (NIST / "Mazak01-20161006-head4000.txt").read_bytes()
    program = (NIST / "NIST_MTC_CRADA_BOX_REV-A OP2 (Front).NC").read_bytes()

    def case(name, mutated, expect="any", **kw):
        c = _case(f"nist/{name}", "b.txt", mutated, expect, extra=("--program", "p.nc"), **kw)
        c.files["p.nc"] = program
        if c.seed:
            c.seed["p.nc"] = program
        return c

    cases = [
        case("hurco-crlf", mutate.line_endings(hurco, b"\r\n"), seed=hurco),
        case("hurco-bom", mutate.BOM + hurco, seed=hurco),
        case("hurco-block-nan", _shdr_value(hurco, rng, b"Block_Number", b"NaN"), "error", lenient="ok"),
        case("hurco-block-fraction", _shdr_value(hurco, rng, b"Block_Number", b"8.5"), "error", lenient="ok"),
        case("hurco-feed-text", _shdr_value(hurco, rng, b"Feed_Rate", b"fast"), "error", lenient="ok"),
        case("hurco-swapped-lines", mutate.swap_lines(hurco, rng, first=2), lenient="any"),
        case("mazak-crlf", mutate.line_endings(mazak, b"\r\n"), seed=mazak),
        case("mazak-xabs-inf", _shdr_value(mazak, rng, b"Xabs", b"inf"), "error", lenient="ok"),
    ]
    for label, data, cuts in (("hurco", hurco, 3), ("mazak", mazak, 2)):
        def labelled(name, *a, _l=label, **kw):
            return case(f"{_l}-{name}", *a, **kw)

        cases += _damaged(labelled, data, rng, cuts=cuts, edits=1)
    # the Hurco's dials and tool (Rapid_Override, Current_Tool): their own generator, so the cases above
    # keep their mutations
    own = random.Random(28)
    for key, values in ((b"Rapid_Override", (b"NaN", b"fast", b"1e400", b"")), (b"Current_Tool", (b"21.5", b"T21", b"inf"))):
        cases += [case(f"hurco-{key.decode().lower()}-{v.decode() or 'empty'}", _shdr_value(hurco, own, key, v), "error",
                       lenient="ok") for v in values]
    cases.append(case("hurco-rapid-override-over-100", _shdr_value(hurco, own, b"Rapid_Override", b"150"), "ok"))
    return cases


def build(rng: random.Random) -> list[Case]:
    return _shdr(rng) + _xml(rng) + _nist(rng)
