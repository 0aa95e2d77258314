"""halsampler capture files -> feedlog streams, on captures generated here (no LinuxCNC needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feedlog.errors import IngestError
from feedlog.ingest.linuxcnc_capture import load_capture, missing_periods, motion_span, servo_t_ns
from feedlog.ingest.linuxcnc_hal import standard_layout
from feedlog.ingest.recording import Recording

PERIOD_NS = 1_000_000


def fake_session(n: int, *, start_tag: int = 0, t0_s: float = 2.345, drop: tuple[int, ...] = (),
                 units: float = 1.0) -> dict[str, np.ndarray]:
    """A 3-axis move: idle, a ramp along X/Y, idle; one value per servo period."""
    tags = np.arange(start_tag, start_tag + n)
    clock = t0_s + np.arange(n) * 1e-3
    moving = (np.arange(n) >= 100) & (np.arange(n) < n - 100)
    s = np.cumsum(moving * 0.05) / units  # 50 mm/s
    keep = np.ones(n, bool)
    keep[list(drop)] = False
    return {"tags": tags[keep], "clock": clock[keep], "x": s[keep], "y": 0.5 * s[keep],
            "moving": moving[keep], "line": np.where(moving, 7, 0)[keep]}


def write_captures(tmp: Path, data: dict[str, np.ndarray], layout) -> list[Path]:
    n = len(data["tags"])
    values = {
        "x_mm": data["x"], "y_mm": data["y"], "z_mm": np.zeros(n), "current_vel": data["moving"] * 50.0,
        "requested_vel": np.full(n, 50.0), "feed_upm": np.full(n, 3000.0), "distance_to_go": np.zeros(n),
        "line": data["line"], "motion_type": data["moving"].astype(int) * 2,
        "in_position": (~data["moving"]).astype(int), "last_period": np.full(n, 2_000_000),
    }
    for j, axis in enumerate("xyz"):
        values[f"j{j}_pos"] = values[f"{axis}_mm"]
        values[f"j{j}_pos_fb"] = values[f"{axis}_mm"]
    files = []
    for k in range(len(layout.groups)):
        names = layout.column_names(k)
        cols = [data["tags"], data["clock"]] + [values[c] for c in names[2:]]
        lines = []
        for row in zip(*cols):
            fields = [str(int(row[0])), f"{row[1]:.6f}"]
            for name, v in zip(names[2:], row[2:]):
                fields.append(str(int(v)) if name in ("line", "motion_type", "in_position", "last_period")
                              else f"{v:.6f}")
            lines.append(" ".join(fields) + " ")  # halsampler ends lines with a space
        path = tmp / f"sampler{k}.txt"
        path.write_text("\n".join(lines) + "\n")
        files.append(path)
    return files


def test_capture_becomes_standard_streams_on_the_servo_grid(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(1000), layout)
    streams, missing = load_capture(files, layout, period_ns=PERIOD_NS)
    assert missing == 0
    assert set(streams) == {"axes", "joints", "feed", "line", "status"}
    t = streams["axes"]["t_ns"].to_numpy()
    assert t.dtype == np.int64 and t[0] == 2_345_000_000
    assert np.all(np.diff(t) == PERIOD_NS)
    feed = streams["feed"]
    assert feed["feed_mm_min"].max() == pytest.approx(3000.0)
    assert feed["requested_feed_mm_min"].iloc[0] == pytest.approx(3000.0)
    assert streams["line"]["line"].dtype == np.int64 and set(streams["line"]["line"]) == {0, 7}
    assert streams["status"]["in_position"].dtype == bool
    Recording(streams=streams)  # passes the recording's own stream checks


def test_inch_machine_positions_and_feeds_are_converted_to_mm(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(600, units=25.4), layout)
    streams, _ = load_capture(files, layout, period_ns=PERIOD_NS, linear_units="inch")
    mm = fake_session(600)["x"]
    np.testing.assert_allclose(streams["axes"]["x_mm"].to_numpy(), mm, atol=1e-4)
    assert streams["feed"]["feed_mm_min"].max() == pytest.approx(50.0 * 25.4 * 60)


def test_missing_servo_periods_are_counted_not_filled(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(800, drop=(300, 301, 302, 500)), layout)
    streams, missing = load_capture(files, layout, period_ns=PERIOD_NS)
    assert missing == 4
    assert len(streams["axes"]) == 796


def test_motion_span_counts_whole_servo_periods_from_first_to_last_move():
    layout = standard_layout("XYZ", 3)
    data = fake_session(1000)
    t = servo_t_ns(data["clock"], PERIOD_NS)
    import pandas as pd
    span = motion_span(pd.DataFrame({"t_ns": t, "x_mm": data["x"], "y_mm": data["y"]}), PERIOD_NS)
    assert (span.first, span.last) == (100, 899)
    assert span.cycle_time_ns == 800 * PERIOD_NS
    still = pd.DataFrame({"t_ns": t, "x_mm": np.zeros(1000)})
    assert motion_span(still, PERIOD_NS) is None
    assert layout.groups  # layout used by the capture tests above


def test_missing_periods_on_grid():
    t = np.array([0, 1, 2, 5, 6, 10], dtype=np.int64) * PERIOD_NS
    assert missing_periods(t, PERIOD_NS) == 2 + 3


def test_truncated_capture_line_names_file_and_line(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(300), layout)
    lines = files[0].read_text().splitlines()
    lines[41] = " ".join(lines[41].split()[:5])
    files[0].write_text("\n".join(lines) + "\n")
    with pytest.raises(IngestError, match=r"sampler0\.txt:42: truncated line"):
        load_capture(files, layout, period_ns=PERIOD_NS)


def test_samplers_out_of_step_are_refused(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(300), layout)
    shifted = [line.split() for line in files[1].read_text().splitlines()]
    for fields in shifted:
        fields[1] = f"{float(fields[1]) + 0.5:.6f}"
    files[1].write_text("\n".join(" ".join(f) for f in shifted) + "\n")
    with pytest.raises(IngestError, match="out of step"):
        load_capture(files, layout, period_ns=PERIOD_NS)


def _retag(path: Path, lines: list[list[str]]) -> None:
    for k, fields in enumerate(lines):
        fields[0] = str(k)
    path.write_text("\n".join(" ".join(f) for f in lines) + "\n")


def test_a_gate_opened_between_two_samplers_drops_the_lone_leading_sample(tmp_path):
    # the enable signal is set from user space: sampler 1 may take one servo period sampler 0 never saw
    layout = standard_layout("XYZ", 3)
    data = fake_session(300)
    files = write_captures(tmp_path, data, layout)
    lines = [line.split() for line in files[1].read_text().splitlines()]
    early = list(lines[0])
    early[1] = f"{data['clock'][0] - 1e-3:.6f}"
    _retag(files[1], [early] + lines)
    streams, missing = load_capture(files, layout, period_ns=PERIOD_NS)
    assert len(streams["axes"]) == 300
    np.testing.assert_allclose(streams["axes"]["x_mm"], data["x"], atol=1e-6)
    assert streams["axes"]["t_ns"].iloc[0] == servo_t_ns(data["clock"][:1], PERIOD_NS)[0]
    assert missing == 0  # the lone sample lies before the session: nothing inside it is missing


def test_a_sampler_that_loses_a_sample_mid_run_is_out_of_step(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(300), layout)
    lines = [line.split() for line in files[1].read_text().splitlines()]
    _retag(files[1], lines[:150] + lines[151:])
    with pytest.raises(IngestError, match="out of step with sampler 0 at sample 151"):
        load_capture(files, layout, period_ns=PERIOD_NS)


def test_wrong_field_count_is_refused(tmp_path):
    layout = standard_layout("XYZAC", 5)
    files = write_captures(tmp_path, fake_session(200), standard_layout("XYZ", 3))
    with pytest.raises((IngestError, ValueError)):
        load_capture(files, layout, period_ns=PERIOD_NS)


def test_capture_cut_mid_line_keeps_every_complete_sample(tmp_path):
    layout = standard_layout("XYZ", 3)
    files = write_captures(tmp_path, fake_session(300), layout)
    for f in files:  # halsampler killed while writing its last line
        text = f.read_text()
        f.write_text(text[:-25])
    streams, missing = load_capture(files, layout, period_ns=PERIOD_NS)
    assert len(streams["axes"]) == 299 and missing == 0
