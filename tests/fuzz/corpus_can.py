"""Fuzz cases for CAN logs: `feedlog import FILE -o out.mcap` on mutated ASC, TRC, BLF and python-can CSV logs,
and on the ASC log with mutated DBC files.

Seeds are the committed axes.* fixtures (one recording in four formats). Mutations: identifiers past
29 bits, frames shorter than their DBC message, blank files, swapped, repeated and dropped frames,
timestamps that are NaN or huge, truncation and bit flips (BLF's compressed containers included).
"""

from __future__ import annotations

import random

from tests.fuzz import mutate
from tests.fuzz.cases import FIXTURES, ROOT, Case, Run

ASC_HEADER = 5  # lines before the first frame in axes.asc


def _case(name: str, files: dict[str, bytes], source: str, expect: str = "any", *, extra: tuple[str, ...] = (),
          max_dropped_ratio: float | None = None, input_name: str | None = None) -> Case:
    name_in_argv = source if ":" not in source else source.split(":", 1)[1]
    argv = ["import", source, *extra, "-o", "out.mcap"]
    return Case("can", f"can/{name}", files, [Run(argv, expect, max_dropped_ratio=max_dropped_ratio)],
                input_name or name_in_argv)


def asc_cases(rng: random.Random) -> list[Case]:
    data = (FIXTURES / "axes.asc").read_bytes()

    def asc(name: str, content: bytes, expect: str = "any", **kw) -> Case:
        return _case(f"asc/{name}", {"a.asc": content}, "a.asc", expect, **kw)

    frame = " 0.500000 1  {id}             Rx   d {dlc} {data}"
    return [
        asc("id-above-29-bits", mutate.insert_line(data, rng, frame.format(id="3FFFFFFFx", dlc=8,
                                                                             data="00 " * 8).encode(), first=6), "error"),
        asc("id-64-bits", mutate.insert_line(data, rng, frame.format(id="FFFFFFFFFFFFFFFFx", dlc=8,
                                                                       data="00 " * 8).encode(), first=6), "error"),
        asc("short-dlc-known-id", mutate.insert_line(data, rng, frame.format(id="100", dlc=2, data="01 02").encode(),
                                                     first=6), "ok", max_dropped_ratio=0.05),
        asc("dlc-0", mutate.insert_line(data, rng, frame.format(id="101", dlc=0, data="").encode(), first=6), "ok"),
        asc("dlc-beyond-data", mutate.insert_line(data, rng, frame.format(id="110", dlc=8, data="01").encode(),
                                                  first=6)),
        asc("blank", b"", "error"),
        asc("blank-lines-only", b"\n\n\n", "error"),
        asc("header-only", b"\n".join(mutate.lines_of(data)[:ASC_HEADER]) + b"\nEnd TriggerBlock\n", "error"),
        asc("no-end-line", data.replace(b"End TriggerBlock", b""), "error"),
        asc("swapped-frames", mutate.swap_lines(data, rng, first=ASC_HEADER), "ok", max_dropped_ratio=0.05),
        asc("repeated-frame", mutate.repeat_line(data, rng, first=ASC_HEADER, times=4), "ok", max_dropped_ratio=0.05),
        asc("dropped-frames", mutate.drop_lines(data, rng, first=ASC_HEADER, count=5), "ok", max_dropped_ratio=0.1),
        # ASC: a line whose time is not digits.digits is another event, not a frame (python-can skips it)
        asc("nan-time", mutate.insert_line(data, rng, b" nan 1  100             Rx   d 8 00 00 00 00 00 00 00 00",
                                           first=6)),
        asc("huge-time", mutate.insert_line(data, rng, b" 99999999999999999999.000000 1  100             Rx   d 8 "
                                                       b"00 00 00 00 00 00 00 00", first=6), "error"),
        asc("garbage-line", mutate.insert_line(data, rng, b"this is not a frame", first=6)),
        asc("bitflip", mutate.flip_bits(data, rng, count=3)),
        asc("truncated", mutate.truncate(data, rng), "error"),
        asc("crlf", mutate.line_endings(data, b"\r\n"), "ok"),
        asc("cr-only", mutate.line_endings(data, b"\r")),
        asc("bom", mutate.BOM + data),
        asc("utf16", mutate.reencode(data, "utf-16"), "error"),
        asc("error-frames", mutate.insert_line(data, rng, b" 0.500000 1  ErrorFrame", first=6), "ok"),
        asc("random-bytes", bytes(rng.randrange(256) for _ in range(2048)), "error"),
    ]


def trc_cases(rng: random.Random) -> list[Case]:
    data = (FIXTURES / "axes.trc").read_bytes()
    first = next(i for i, line in enumerate(mutate.lines_of(data)) if line.strip() and not line.startswith(b";"))

    def trc(name: str, content: bytes, expect: str = "any", **kw) -> Case:
        return _case(f"trc/{name}", {"a.trc": content}, "a.trc", expect, **kw)

    return [
        trc("truncated", mutate.truncate(data, rng), "error"),
        trc("bitflip-a", mutate.flip_bits(data, rng)),
        trc("bitflip-b", mutate.flip_bits(data, rng, count=4)),
        trc("swapped-frames", mutate.swap_lines(data, rng, first=first), "ok", max_dropped_ratio=0.05),
        trc("garbage-line", mutate.insert_line(data, rng, b"     99  what", first=first)),
        trc("huge-id", mutate.insert_line(data, rng, b"     99         1.000 DT  1     FFFFFFFFF Rx -  8    "
                                                     b"00 00 00 00 00 00 00 00", first=first)),
        trc("blank", b"", "error"),
        trc("header-only", b"\n".join(mutate.lines_of(data)[:first]) + b"\n", "error"),
    ]


def blf_cases(rng: random.Random) -> list[Case]:
    data = (FIXTURES / "axes.blf").read_bytes()

    def blf(name: str, content: bytes, expect: str = "any") -> Case:
        return _case(f"blf/{name}", {"a.blf": content}, "a.blf", expect)

    cases = [blf(f"truncated-{k}", mutate.truncate(data, rng), "error") for k in range(3)]
    cases += [blf(f"bitflip-{k}", mutate.flip_bits(data, rng, start=144)) for k in range(4)]
    cases += [
        blf("bitflip-header", mutate.flip_bits(data, rng, end=144)),
        blf("header-size-huge", data[:8] + (2**31 - 1).to_bytes(4, "little") + data[12:]),
        blf("file-size-huge", data[:16] + (2**62).to_bytes(8, "little") + data[24:], "error"),
        blf("object-count-huge", data[:32] + (2**32 - 1).to_bytes(4, "little") + data[36:]),
        blf("object-size-2gb", data[:144 + 8] + (2**31 - 1).to_bytes(4, "little") + data[144 + 12:]),
        blf("object-size-4gb", data[:144 + 8] + (2**32 - 16).to_bytes(4, "little") + data[144 + 12:]),
        blf("empty", b"", "error"),
        blf("random-bytes", b"LOGG" + bytes(rng.randrange(256) for _ in range(3000))),
    ]
    return cases


def canlog_csv_cases(rng: random.Random) -> list[Case]:
    data = (FIXTURES / "axes.csv").read_bytes()

    def csv(name: str, content: bytes, expect: str = "any", **kw) -> Case:
        return _case(f"canlog-csv/{name}", {"a.csv": content}, "can:a.csv", expect, **kw)

    return [
        csv("huge-id", mutate.insert_line(data, rng, b"1700000000.5,0xFFFFFFFFFFFF,1,0,0,8,AAAAAAAAAAA=", first=1),
            "error"),
        csv("id-30-bits", mutate.insert_line(data, rng, b"1700000000.5,0x3FFFFFFF,1,0,0,8,AAAAAAAAAAA=", first=1), "error"),
        csv("bad-base64", mutate.insert_line(data, rng, b"1700000000.5,0x100,0,0,0,8,@@@@", first=1)),
        csv("nan-time", mutate.insert_line(data, rng, b"nan,0x100,0,0,0,8,AAAAAAAAAAA=", first=1), "error"),
        csv("short-frame", mutate.insert_line(data, rng, b"1700000000.5,0x100,0,0,0,2,AAA=", first=1), "ok",
            max_dropped_ratio=0.05),
        csv("truncated", mutate.truncate(data, rng), "error"),
        csv("swapped", mutate.swap_lines(data, rng, first=1), "ok", max_dropped_ratio=0.05),
        csv("header-only", mutate.lines_of(data)[0] + b"\n", "error"),
    ]


def dbc_cases(rng: random.Random) -> list[Case]:
    asc = (FIXTURES / "axes.asc").read_bytes()
    dbc = (ROOT / "src" / "feedlog" / "ingest" / "feedlog_axes.dbc").read_bytes()

    def with_dbc(name: str, content: bytes, expect: str = "any") -> Case:
        return _case(f"dbc/{name}", {"a.asc": asc, "x.dbc": content}, "a.asc", expect, extra=("--dbc", "x.dbc"),
                     input_name="x.dbc")

    return [
        with_dbc("truncated", mutate.truncate(dbc, rng)),
        with_dbc("bitflip", mutate.flip_bits(dbc, rng, count=2)),
        with_dbc("signal-65-bits", dbc.replace(b"x_mm : 0|28@1-", b"x_mm : 0|65@1-"), "error"),
        with_dbc("signal-past-frame", dbc.replace(b"y_mm : 28|28@1-", b"y_mm : 60|28@1-"), "error"),
        with_dbc("signal-0-bits", dbc.replace(b"x_mm : 0|28@1-", b"x_mm : 0|0@1-"), "error"),
        with_dbc("scale-zero", dbc.replace(b"(0.0001,0)", b"(0,0)", 1)),
        with_dbc("empty", b"", "error"),
        with_dbc("utf16", mutate.reencode(dbc, "utf-16"), "error"),
    ]


def build(rng: random.Random) -> list[Case]:
    return asc_cases(rng) + trc_cases(rng) + blf_cases(rng) + canlog_csv_cases(rng) + dbc_cases(rng)
