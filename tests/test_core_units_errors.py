"""Units convert at the edges; errors render file, line and position in one line."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.errors import FeedlogError, IngestError, ProgramError, UnitError
from feedlog.units import (angle_factor, length_factor, ns_to_seconds, seconds_to_ns, time_factor,
                           velocity_factor)


def test_length_and_time_factors():
    assert length_factor("in") == 25.4
    assert length_factor("M") == 1000.0
    assert time_factor("ms") == 1e-3
    assert angle_factor("rad") == pytest.approx(57.29577951308232)


@pytest.mark.parametrize("unit, mm_min", [("mm/min", 1.0), ("mm/s", 60.0), ("in/min", 25.4), ("m/s", 60000.0)])
def test_velocity_factor_to_mm_per_min(unit, mm_min):
    assert velocity_factor(unit) == pytest.approx(mm_min)


@pytest.mark.parametrize("bad", ["furlong", "mm", "mm/fortnight"])
def test_unknown_units_raise_unit_error(bad):
    with pytest.raises(UnitError):
        velocity_factor(bad) if "/" in bad or bad == "mm" else length_factor(bad)


def test_seconds_ns_round_trip_is_exact_at_ns_resolution():
    t = np.array([0.0, 0.001, 1.5, 3600.000000001])
    ns = seconds_to_ns(t)
    assert ns.dtype == np.int64
    assert list(ns) == [0, 1_000_000, 1_500_000_000, 3_600_000_000_001]
    assert np.allclose(ns_to_seconds(ns), t)


def test_program_error_names_file_line_and_code():
    err = ProgramError("unsupported G-code", file="part.ngc", line=12, code="G5.2")
    assert str(err) == "part.ngc:12: unsupported G-code [G5.2]"
    assert isinstance(err, FeedlogError)
    assert (err.file, err.line, err.code) == ("part.ngc", 12, "G5.2")


def test_ingest_error_names_the_record_position():
    err = IngestError("truncated chunk", file="rec.mcap", position="byte 4096")
    assert str(err) == "rec.mcap (byte 4096): truncated chunk"
