"""Fuzz cases for MCAP: `feedlog info` (strict and --recover) and `feedlog import` on damaged recordings,
and `feedlog import --map` on damaged generic JSON MCAP.

Seeds: a six-second feedlog recording written in 64 KiB chunks (zstd, lz4, uncompressed), the
committed format-v1 fixture and the generic JSON fixture. Mutations: truncation at and around every
chunk end, bit flips inside compressed and plain chunks, length fields far beyond the file (the 2.5 KB
file that once allocated 4.3 GB), swapped records, wrong CRCs and compressions, and damage that the
CRC cannot see (messages edited and the CRC computed again): NaN values, INT64_MIN times, short
Arrow buffers, JSON with NaN, strings and missing fields.
"""

from __future__ import annotations

import random
import struct

import numpy as np
from mcap.opcode import Opcode

from tests.fuzz import mcap_edit as me
from tests.fuzz import mutate
from tests.fuzz.cases import FIXTURES, Case, Run

NAME = "r.mcap"


def _runs(strict: str = "any", recover: str = "any") -> list[Run]:
    return [Run(["info", NAME, "--json"], strict), Run(["info", NAME, "--json", "--recover"], recover),
            Run(["import", NAME, "-o", "out.mcap"], strict),
            Run(["import", NAME, "--recover", "-o", "out.mcap"], recover)]


def _case(name: str, data: bytes, strict: str = "any", recover: str = "any") -> Case:
    return Case("mcap", f"mcap/{name}", {NAME: data}, _runs(strict, recover), NAME)


def seeds() -> dict[str, bytes]:
    streams = me.seed_streams()
    return {
        "zstd": me.write_feedlog(streams, chunk_size=64 * 1024, compression="zstd", rows_per_message=500),
        "lz4": me.write_feedlog(streams, chunk_size=64 * 1024, compression="lz4", rows_per_message=500),
        "none": me.write_feedlog(streams, chunk_size=32 * 1024, compression="none", rows_per_message=250),
        "fixture": (FIXTURES / "format_v1.mcap").read_bytes(),
    }


def truncations(rng: random.Random, data: bytes) -> list[Case]:
    """Cut at every chunk end (what a killed logger leaves) and a few bytes either side of some."""
    cases = []
    ends = me.chunk_ends(data)
    for k, end in enumerate(ends[:-1]):
        cases.append(_case(f"zstd/cut-after-chunk-{k}", data[:end], "error", "ok"))
    for k, end in enumerate(rng.sample(ends, 3)):
        cases.append(_case(f"zstd/cut-inside-chunk-{k}", data[:end - rng.randrange(1, 200)], "error", "ok"))
        cases.append(_case(f"zstd/cut-after-chunk-plus-{k}", data[:end + rng.randrange(1, 9)], "error", "ok"))
    return cases


def length_fields(data: bytes, label: str) -> list[Case]:
    """Length fields that point far past the end of a small file."""
    recs = me.records(data)
    chunk = recs[me.first(recs, Opcode.CHUNK)]
    fields = me.chunk_fields(chunk)
    header_profile = recs[0].offset + 9  # Header: profile string length first
    cases = [
        _case(f"{label}/header-string-4gb", me.set_u32(data, header_profile, 0xFFFF_FFFF), "error", "error"),
        _case(f"{label}/header-length-2e40", me.set_length(data, 0, 2**40), "error", "error"),
        _case(f"{label}/metadata-length-2e62", me.set_length(data, 1, 2**62), "error", "any"),
        _case(f"{label}/chunk-length-2e40", me.set_length(data, me.first(recs, Opcode.CHUNK), 2**40), "error", "any"),
        _case(f"{label}/chunk-uncompressed-4gb", me.set_u64(data, fields["uncompressed_size"], 2**32 + 5), "error",
              "any"),
        _case(f"{label}/chunk-uncompressed-2e62", me.set_u64(data, fields["uncompressed_size"], 2**62), "error", "any"),
        _case(f"{label}/chunk-records-2e63", me.set_u64(data, fields["records_length"], 2**63), "error", "any"),
        _case(f"{label}/chunk-compression-4gb", me.set_u32(data, fields["compression"], 0xFFFF_FFFF), "error", "any"),
        _case(f"{label}/chunk-crc-wrong", me.set_u32(data, fields["crc"], 12345), "error", "any"),
    ]
    attach = [r for r in recs if r.opcode == Opcode.ATTACHMENT]
    if attach:
        cases.append(_case(f"{label}/attachment-length-2e40", me.set_length(data, recs.index(attach[0]), 2**40),
                           "error", "any"))
    return cases


def hidden_damage(data: bytes, label: str) -> list[Case]:
    """Messages edited and the chunk CRC recomputed: only the reader's own checks can catch these."""

    def nan_values(msg) -> bytes:
        raw = bytearray(msg.data)
        raw[-8:] = struct.pack("<d", float("nan"))  # the last value of the last column
        return bytes(raw)

    def first_time_min(msg) -> bytes:
        raw = bytearray(msg.data)
        k = raw.find(struct.pack("<q", 1_000_000_000))  # the first t_ns of the recording
        if k >= 0:
            raw[k:k + 8] = struct.pack("<q", np.iinfo(np.int64).min)
        return bytes(raw)

    def half(msg) -> bytes:
        return msg.data[: len(msg.data) // 2]

    def rows_huge(msg) -> bytes:
        raw = bytearray(msg.data)
        n = 500 if label == "zstd" else 250
        k = raw.find(struct.pack("<q", n))  # the batch's length field in the flatbuffer
        if k >= 0:
            raw[k:k + 8] = struct.pack("<q", 2**40)
        return bytes(raw)

    def empty(msg) -> bytes:
        return b""

    return [
        _case(f"{label}/hidden-nan-value", me.edit_messages(data, nan_values), "error", "error"),
        _case(f"{label}/hidden-int64-min-time", me.edit_messages(data, first_time_min), "error", "error"),
        _case(f"{label}/hidden-half-batches", me.edit_messages(data, half), "error", "error"),
        _case(f"{label}/hidden-rows-2e40", me.edit_messages(data, rows_huge), "error", "error"),
        _case(f"{label}/hidden-empty-messages", me.edit_messages(data, empty), "error", "error"),
    ]


def structural(rng: random.Random, data: bytes) -> list[Case]:
    recs = me.records(data)
    chunks = [i for i, r in enumerate(recs) if r.opcode == Opcode.CHUNK]
    swapped = list(recs)
    swapped[chunks[1]], swapped[chunks[3]] = swapped[chunks[3]], swapped[chunks[1]]
    late_meta = [r for r in recs if r.opcode != Opcode.METADATA] + [r for r in recs if r.opcode == Opcode.METADATA]
    no_format = [r for r in recs if not (r.opcode == Opcode.METADATA and r.body[:11] == b"\x07\x00\x00\x00feedlog")]
    at = me.chunk_fields(recs[chunks[0]])["compression"] + 4
    bad_compression = data[:at] + b"brot" + data[at + 4:]  # "zstd" -> "brot"
    return [
        _case("zstd/swapped-chunks", me.join(swapped), "error", "error"),
        _case("zstd/metadata-last", me.join(late_meta), "any", "any"),
        _case("zstd/chunks-only", me.join([r for r in recs if r.opcode == Opcode.CHUNK]), "error", "error"),
        _case("zstd/no-format-metadata", me.join(no_format), "error", "error"),
        _case("zstd/format-version-2", data.replace(b"format_version\x01\x00\x00\x001", b"format_version\x01\x00\x00\x002"),
              "error", "error"),
        _case("zstd/dropped-frames-text", data.replace(b"dropped_frames\x01\x00\x00\x000", b"dropped_frames\x01\x00\x00\x00x"),
              "error", "error"),
        _case("zstd/dropped-frames-30-digits", me.replace_metadata(data, "feedlog.stats", {
            "dropped_frames": "9" * 30, "closed": "true"}), "error", "error"),
        _case("zstd/dropped-frames-negative", me.replace_metadata(data, "feedlog.stats", {
            "dropped_frames": "-5", "closed": "true"}), "error", "error"),
        _case("zstd/unknown-compression", bad_compression, "error", "any"),
        _case("empty", b"", "error", "error"),
        _case("magic-only", me.MAGIC, "error", "error"),
        _case("magic-and-header", data[:recs[1].offset], "error", "any"),
        _case("random-2500-bytes", me.MAGIC + bytes(rng.randrange(256) for _ in range(2500)), "error", "error"),
    ]


def flips(rng: random.Random, seeds_: dict[str, bytes]) -> list[Case]:
    cases = []
    for label in ("zstd", "lz4", "none"):
        data = seeds_[label]
        recs = me.records(data)
        chunk = recs[me.first(recs, Opcode.CHUNK)]
        inside = me.chunk_fields(chunk)["records"]
        for k in range(3):  # inside a chunk's payload: zstd/lz4 errors or the CRC must catch every one
            cases.append(_case(f"{label}/chunk-bitflip-{k}", mutate.flip_bits(data, rng, start=inside + 16,
                                                                             end=chunk.end), "error", "ok"))
    for label in ("zstd", "fixture"):
        for k in range(4):
            cases.append(_case(f"{label}/bitflip-anywhere-{k}", mutate.flip_bits(seeds_[label], rng)))
        for k in range(2):
            cases.append(_case(f"{label}/truncated-{k}", mutate.truncate(seeds_[label], rng), "error", "any"))
    return cases


def generic_json(rng: random.Random) -> list[Case]:
    data = (FIXTURES / "generic_json.mcap").read_bytes()
    mapping = "x=/robot/pose:pos.x,y=/robot/pose:pos.y,z=/robot/pose:pos.z"

    def case(name: str, content: bytes, strict: str = "any", lenient: str = "any") -> Case:
        argv = ["import", NAME, "--map", mapping, "-o", "out.mcap"]
        return Case("mcap", f"mcap/json/{name}", {NAME: content},
                    [Run(argv, strict), Run(argv + ["--lenient"], lenient)], NAME)

    def payload(text: str):
        def change(msg) -> bytes:  # the sixth message of fifty
            return text.encode() if msg.log_time == 2_100_000_000 else msg.data
        return change

    return [
        case("nan-value", me.edit_messages(data, payload('{"pos": {"x": NaN, "y": 1, "z": 0}}')), "error", "ok"),
        case("infinity-value", me.edit_messages(data, payload('{"pos": {"x": Infinity, "y": 1, "z": 0}}')), "error",
             "ok"),
        case("1e400-value", me.edit_messages(data, payload('{"pos": {"x": 1e400, "y": 1, "z": 0}}')), "error", "ok"),
        case("string-value", me.edit_messages(data, payload('{"pos": {"x": "abc", "y": 1, "z": 0}}')), "error", "ok"),
        case("missing-field", me.edit_messages(data, payload('{"pos": {"y": 1, "z": 0}}')), "error", "ok"),
        case("not-json", me.edit_messages(data, payload('{"pos": ')), "error", "ok"),
        case("list-not-object", me.edit_messages(data, payload('[1, 2, 3]')), "error", "ok"),
        case("truncated", mutate.truncate(data, rng), "error", "error"),
        case("bitflip", mutate.flip_bits(data, rng, count=2)),
    ]


def build(rng: random.Random) -> list[Case]:
    s = seeds()
    cases = truncations(rng, s["zstd"])
    for label in ("zstd", "none", "fixture"):
        cases += length_fields(s[label], label)
    for label in ("zstd", "none"):
        cases += hidden_damage(s[label], label)
    return cases + structural(rng, s["zstd"]) + flips(rng, s) + generic_json(rng)
