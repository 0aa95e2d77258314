"""Seeded fuzzing (hypothesis, derandomized) of what the OPC UA source reads from files and servers: node
maps and security files (truncated, bit-flipped, other encodings), engineering units and values of
any type. Each either gives what it promises or raises our one-line IngestError."""

from __future__ import annotations

import datetime as dt
import math
from importlib import resources

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import IngestError
from feedlog.ingest.source_opcua import TARGETS, load_node_map, security_settings, to_ns, unit_from_eu, value_text
from tests.fuzz.test_fuzz_mtconnect_live import MUTATIONS, mutated

FUZZ = settings(max_examples=150, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))
SINUMERIK = (resources.files("feedlog.ingest") / "opcua_nodes" / "sinumerik.toml").read_bytes()
SECURITY = (b'policy = "Basic256Sha256"\nmode = "SignAndEncrypt"\ncertificate = "c.der"\nprivate_key = "k.pem"\n'
            b'user = "operator"\npassword = "pw"\n')


@FUZZ
@given(st.sampled_from(MUTATIONS), st.integers(0, 2**32 - 1))
def test_node_maps_load_or_fail_with_one_line(tmp_path_factory, kind, seed):
    path = tmp_path_factory.mktemp("map") / "m.toml"
    path.write_bytes(mutated(SINUMERIK, kind, seed))
    try:
        nmap = load_node_map(str(path))
    except IngestError as exc:
        assert "\n" not in str(exc)
        return
    assert nmap.columns and set(nmap.columns) <= set(TARGETS)
    assert all(isinstance(node, str) for node, _ in nmap.columns.values())


@FUZZ
@given(st.sampled_from(MUTATIONS), st.integers(0, 2**32 - 1))
def test_security_files_load_or_fail_with_one_line(tmp_path_factory, kind, seed):
    path = tmp_path_factory.mktemp("sec") / "s.toml"
    path.write_bytes(mutated(SECURITY, kind, seed))
    try:
        found = security_settings(str(path), {})
    except IngestError as exc:
        assert "\n" not in str(exc) and "pw" not in str(exc).replace(str(path), "")
        return
    assert all(isinstance(v, str) for v in found.values())


class EU:
    def __init__(self, unit_id, text) -> None:
        self.UnitId = unit_id
        self.DisplayName = type("T", (), {"Text": text})()


@FUZZ
@given(st.one_of(st.none(), st.integers(-2**40, 2**40)), st.one_of(st.none(), st.text(max_size=12)))
def test_engineering_units_never_crash(unit_id, text):
    unit = unit_from_eu(EU(unit_id, text))
    assert unit is None or isinstance(unit, str)


VALUES = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=20),
                   st.lists(st.text(max_size=5), max_size=4), st.binary(max_size=8))


@FUZZ
@given(VALUES)
def test_values_become_text(value):
    text = value_text(value)
    assert isinstance(text, str)
    if isinstance(value, float) and math.isfinite(value):
        assert float(text) == value


def test_timestamps():
    assert to_ns(dt.datetime(2026, 1, 1, tzinfo=dt.UTC)) == 1767225600 * 10**9
    assert to_ns(dt.datetime(2026, 1, 1, 0, 0, 0, 1)) == 1767225600 * 10**9 + 1000   # naive: UTC
    assert to_ns(dt.datetime(1601, 1, 1)) is None and to_ns(None) is None


def test_map_entries_with_the_wrong_shape_are_errors(tmp_path):
    path = tmp_path / "m.toml"
    for text, message in [("columns = 3", "must be tables"), ("[columns]\n", "has no \\[columns\\]"),
                          ("[columns]\nx = {unit = 'mm'}", "give node ="), ("[columns]\nx='a'\n[events]\np=1", "as a string")]:
        path.write_text(text)
        with pytest.raises(IngestError, match=message):
            load_node_map(str(path))
