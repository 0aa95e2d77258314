"""Fixed-rate CSV without a time column (--rate-hz), the UMich and Sinumerik presets, the feed unit check."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.errors import IngestError
from feedlog.ingest.csv_reader import read_csv
from feedlog.ingest.mapping import ColumnMap, load_preset, parse_map
from feedlog.ingest.readers import ImportOptions, read_source
from feedlog.ingest.recording import Recording
from feedlog.ingest.unit_check import feed_unit_check

REAL = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"


def test_rate_hz_gives_row_index_times_and_a_dropped_row_keeps_its_slot(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("X,F\n0,100\n1,100\nbad,100\n3,100\n")
    cmap = ColumnMap(mapping=parse_map("x=X,feed=F"), rate_hz=4.0)
    with pytest.raises(IngestError, match=r"r\.csv:4: "):
        read_csv(path, cmap)
    rec = read_csv(path, cmap, strict=False)
    assert rec.streams["axes"]["t_ns"].tolist() == [0, 250_000_000, 750_000_000]
    assert "row index / 4 Hz" in rec.metadata["units"]
    with pytest.raises(IngestError, match="names a time column .* and a fixed rate"):
        ColumnMap(mapping=parse_map("t=T,x=X"), rate_hz=4.0)
    with pytest.raises(IngestError, match="rate_hz must be"):
        ColumnMap(mapping=parse_map("x=X"), rate_hz=-1.0)
    with pytest.raises(IngestError, match="no time column: add t=<column>, or .*--rate-hz"):
        ColumnMap(mapping=parse_map("x=X"))


def test_umich_preset_reads_the_tool_wear_columns_at_10_hz():
    rec = read_source(REAL / "umich_experiment.csv", ImportOptions(preset="umich-tool-wear"))
    axes = rec.streams["axes"]
    assert np.diff(axes["t_ns"]).tolist() == [100_000_000] * (len(axes) - 1)
    raw = pd.read_csv(REAL / "umich_experiment.csv")
    np.testing.assert_allclose(axes["x_mm"], raw["X1_ActualPosition"])
    # the public files' sequence column is a counter, not N words: kept apart, never a block number
    assert "line" not in rec.streams
    assert rec.streams["program"]["sequence_number"].tolist() == raw["M1_sequence_number"].tolist()
    # the feed column is mm/s (the velocity columns agree): 60 x in mm/min
    np.testing.assert_allclose(rec.streams["feed"]["requested_feed_mm_min"], raw["M1_CURRENT_FEEDRATE"] * 60.0)
    np.testing.assert_allclose(rec.streams["velocity"]["x_mm_s"], raw["X1_ActualVelocity"])
    assert rec.metadata["controller"] == "umich-tool-wear"


def test_sinumerik_preset_semicolons_comment_line_and_bracketed_names():
    rec = read_source(REAL / "sinumerik_trace.csv", ImportOptions(preset="sinumerik-trace"))
    assert set(rec.streams) == {"axes", "feed", "line", "spindle"}
    assert np.diff(rec.streams["axes"]["t_ns"]).max() == 20_000_000
    assert parse_map("t=Time,x=/C/pos[u1,1],y=/C/pos[u1,2]") == {"t": "Time", "x": "/C/pos[u1,1]",
                                                                  "y": "/C/pos[u1,2]"}
    with pytest.raises(IngestError, match="comment must be"):
        ColumnMap(**{**load_preset("sinumerik-trace").__dict__, "comment": ""})


def recording(feed_mm_min: float, speed_mm_min: float) -> Recording:
    t = np.arange(50, dtype=np.int64) * 10_000_000
    x = np.arange(50) * speed_mm_min / 60.0 * 0.01
    return Recording(streams={"axes": pd.DataFrame({"t_ns": t, "x_mm": x, "y_mm": 0.0 * x}),
                              "feed": pd.DataFrame({"t_ns": t, "feed_mm_min": np.full(50, feed_mm_min)})})


@pytest.mark.parametrize(("feed", "says"), [(1000.0, None), (1000.0 / 60.0, "per second"), (60000.0, "per minute"),
                                            (1000.0 / 25.4, "in inches"), (3700.0, "check the declared")])
def test_unit_check_names_the_likely_mistake(feed, says):
    check = feed_unit_check(recording(feed, 1000.0))
    assert check.ratio == pytest.approx(feed / 1000.0, rel=1e-6)
    if says is None:
        assert check.warning is None
    else:
        assert says in check.warning


def test_unit_check_needs_both_witnesses():
    rec = recording(1000.0, 1000.0)
    del rec.streams["feed"]
    assert feed_unit_check(rec) is None
    assert feed_unit_check(recording(0.0, 0.0)) is None
