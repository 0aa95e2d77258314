"""Seeded fuzzing (hypothesis, derandomized) of what the live MTConnect source reads from an agent: probe
documents, streams documents and multipart byte streams, truncated, bit-flipped, with bytes inserted
or lost, and in other encodings. Each parser either returns what it promises (observations with
sequence numbers, rows with finite values and int64 times that never go back) or raises our one-line
IngestError; nothing allocates beyond the input's size."""

from __future__ import annotations

import random
import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import IngestError
from feedlog.ingest.mtconnect_agent import MAX_DOCUMENT_BYTES, MultipartReader, parse_probe, parse_streams
from feedlog.ingest.live_rows import Pivot
from feedlog.ingest.source_mtconnect import observation_times, plan_items
from feedlog.units import MAX_ABS_T_NS
from tests.fuzz import mutate
from tests.ingest.mtconnect_test_agent import BOUNDARY, ITEMS, probe_xml

FUZZ = settings(max_examples=120, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))

PROBE = probe_xml()
PLAN = plan_items(parse_probe(PROBE)[0])


def streams_doc() -> bytes:
    obs = "".join(f'<Position dataItemId="{item}" timestamp="2026-01-01T00:00:0{k % 10}.{k:06d}Z" sequence="{100 + k}" '
                  f'subType="ACTUAL">{1.5 * k}</Position>' for k, item in enumerate(["Xact", "Yact", "Zact"] * 3))
    events = ('<LineNumber dataItemId="ln" timestamp="2026-01-01T00:00:01Z" sequence="120">12</LineNumber>'
              '<Execution dataItemId="exec" timestamp="2026-01-01T00:00:01Z" sequence="121">ACTIVE</Execution>'
              '<PathFeedrate dataItemId="pf" timestamp="2026-01-01T00:00:01Z" sequence="122">UNAVAILABLE</PathFeedrate>')
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<MTConnectStreams xmlns="urn:mtconnect.org:MTConnectStreams:1.3">'
            '<Header creationTime="2026-01-01T00:00:02Z" instanceId="7" firstSequence="1" lastSequence="122" '
            'nextSequence="123" bufferSize="4096"/><Streams><DeviceStream name="LinuxCNC" uuid="u">'
            f'<ComponentStream component="Linear" name="X"><Samples>{obs}</Samples></ComponentStream>'
            f'<ComponentStream component="Path" name="path"><Events>{events}</Events></ComponentStream>'
            '</DeviceStream></Streams></MTConnectStreams>').encode()


STREAMS = streams_doc()
MUTATIONS = ("truncate", "flip", "insert", "delete", "utf16", "latin1", "bom", "crlf", "none")


def mutated(data: bytes, kind: str, seed: int) -> bytes:
    rng = random.Random(seed)
    if kind == "truncate":
        return mutate.truncate(data, rng)
    if kind == "flip":
        return mutate.flip_bits(data, rng, count=1 + seed % 5)
    if kind == "insert":
        return mutate.insert_bytes(data, rng)
    if kind == "delete":
        return mutate.delete_bytes(data, rng)
    if kind == "utf16":
        return data.decode().encode("utf-16")
    if kind == "latin1":
        return data.replace(b'encoding="UTF-8"', b'encoding="ISO-8859-1"').replace(b"UNAVAILABLE", "\u00b5m".encode("latin-1"))
    if kind == "bom":
        return mutate.BOM + data
    if kind == "crlf":
        return mutate.line_endings(data, b"\r\n")
    return data


@FUZZ
@given(st.sampled_from(MUTATIONS), st.integers(0, 2**32 - 1))
def test_probe_documents_parse_to_data_items_or_one_error(kind, seed):
    data = mutated(PROBE, kind, seed)
    try:
        devices = parse_probe(data, where="http://agent/probe")
    except IngestError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("http://agent/probe")
        return
    for device in devices:
        assert all(item.id for item in device.items)
        try:
            plan = plan_items(device)
        except IngestError as exc:
            assert "\n" not in str(exc)
            continue
        assert all(np.isfinite(c.factor) and c.factor >= 0 for c in plan.columns.values())


@FUZZ
@given(st.sampled_from(MUTATIONS), st.integers(0, 2**32 - 1))
def test_streams_documents_become_finite_ordered_rows_or_one_error(kind, seed):
    data = mutated(STREAMS, kind, seed)
    try:
        doc = parse_streams(data, where="http://agent/sample")
    except IngestError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("http://agent/sample")
        return
    assert all(0 <= o.sequence < 10**19 for o in doc.observations)
    pivot = Pivot(PLAN)
    times = observation_times(doc.observations, 1_800_000_000_000_000_000)
    frames = [pivot.feed(doc.observations, times), pivot.release()]
    for part in frames:
        for stream, table in part.items():
            t = table["t_ns"].to_numpy()
            assert t.dtype == np.int64 and (np.abs(t) <= MAX_ABS_T_NS).all() and (np.diff(t) >= 0).all()
            if stream != "events":
                assert np.isfinite(table.iloc[:, 1:].to_numpy(dtype=np.float64)).all()


def multipart(parts: list[bytes]) -> bytes:
    out = b""
    for body in parts:
        out += (f"--{BOUNDARY}\r\nContent-type: text/xml\r\nContent-length: {len(body)}\r\n\r\n").encode() + body + b"\r\n"
    return out


def reader_of(data: bytes, sizes: list[int]):
    pos = [0]
    steps = iter(sizes * (len(data) + 1))

    def read(n: int) -> bytes:
        k = min(n, next(steps))
        chunk = data[pos[0]:pos[0] + k]
        pos[0] += len(chunk)
        return chunk
    return read


@FUZZ
@given(st.sampled_from(MUTATIONS[:4] + ("none",)), st.integers(0, 2**32 - 1),
       st.lists(st.integers(1, 700), min_size=1, max_size=8))
def test_multipart_streams_split_into_whole_parts_or_one_error(kind, seed, sizes):
    good = [STREAMS, STREAMS.replace(b'sequence="1', b'sequence="2')]
    data = mutated(multipart(good), kind, seed)
    try:
        parts = list(MultipartReader(reader_of(data, sizes), BOUNDARY, where="http://agent/sample"))
    except IngestError as exc:
        assert "\n" not in str(exc)
        return
    assert len(parts) <= 2 + data.count(b"--" + BOUNDARY.encode())
    if kind == "none":
        assert [body for _, body in parts] == good
    for _, body in parts:
        assert len(body) <= len(data)
        try:
            parse_streams(body)
        except IngestError:
            pass


def test_a_part_claiming_gigabytes_is_refused_without_allocating_them():
    data = f"--{BOUNDARY}\r\nContent-type: text/xml\r\nContent-length: {50 * MAX_DOCUMENT_BYTES}\r\n\r\n<x/>".encode()
    tracemalloc.start()
    try:
        with pytest.raises(IngestError, match="a multipart part of"):
            list(MultipartReader(reader_of(data, [64]), BOUNDARY))
        assert tracemalloc.get_traced_memory()[1] < 1 << 20
    finally:
        tracemalloc.stop()
    # a part within the limit that never arrives whole is not a part
    cut = f"--{BOUNDARY}\r\nContent-length: 4000\r\n\r\n<x/>".encode()
    assert list(MultipartReader(reader_of(cut, [7]), BOUNDARY)) == []
    with pytest.raises(IngestError, match="at most"):
        parse_streams(b" " * (MAX_DOCUMENT_BYTES + 1))


def test_documents_without_sequences_or_of_another_kind_are_one_line_errors():
    with pytest.raises(IngestError, match="without a dataItemId and a sequence"):
        parse_streams(STREAMS.replace(b' sequence="100"', b""))
    with pytest.raises(IngestError, match="not an MTConnect streams response"):
        parse_streams(PROBE)
    with pytest.raises(IngestError, match="not an MTConnect probe response"):
        parse_probe(STREAMS)
    with pytest.raises(IngestError, match="UTF-16"):
        parse_streams(STREAMS.decode().encode("utf-16"))
    error = parse_streams(b'<MTConnectError><Header/><Errors><Error errorCode="OUT_OF_RANGE">late</Error></Errors>'
                          b"</MTConnectError>")
    assert error.errors == [("OUT_OF_RANGE", "late")]
    assert set(ITEMS) >= {i.id for i in parse_probe(PROBE)[0].items}


def test_digits_that_are_not_ascii_are_not_numbers():
    # latin-1 0xB2 is '²', which str.isdigit() accepts and int() refuses
    with pytest.raises(IngestError, match="without a dataItemId and a sequence"):
        parse_streams(STREAMS.replace(b'sequence="100"', 'sequence="1\u00b2"'.encode()))
    data = f"--{BOUNDARY}\r\nContent-length: 1\xb2\r\n\r\n<x/>".encode("latin-1")
    with pytest.raises(IngestError, match="Content-length"):
        list(MultipartReader(reader_of(data, [64]), BOUNDARY))
