"""The recorder's HAL layout and the haltcl text it generates."""

from __future__ import annotations

import pytest

from feedlog.ingest.linuxcnc_hal import (ENABLE_SIGNAL, MAX_PINS_PER_SAMPLER, Column, SamplerLayout,
                                         recorder_tcl, standard_layout)


def test_xyz_layout_puts_axes_and_status_first_and_joints_second():
    layout = standard_layout("XYZ", 3)
    assert layout.channels == [0, 1]
    names0 = layout.column_names(0)
    assert names0[:5] == ["sample", "clock_s", "x_mm", "y_mm", "z_mm"]
    assert {"current_vel", "requested_vel", "line", "in_position", "motion_type"} <= set(names0)
    assert layout.column_names(1)[2:] == ["j0_pos", "j0_pos_fb", "j1_pos", "j1_pos_fb", "j2_pos", "j2_pos_fb"]
    # the clock is a float; program-line and motion-type are s32, in-position a bit
    cfg = layout.cfgs[0]
    assert cfg[0] == "f" and len(cfg) == len(names0) - 1
    assert cfg[names0.index("line") - 1] == "s" and cfg[names0.index("in_position") - 1] == "b"


def test_xyzac_layout_names_rotaries_in_degrees_and_fits_samplers():
    layout = standard_layout("XYZAC", 5)
    assert layout.column_names(0)[2:7] == ["x_mm", "y_mm", "z_mm", "a_deg", "c_deg"]
    for k in range(len(layout.groups)):
        assert len(layout.column_names(k)) - 1 <= MAX_PINS_PER_SAMPLER
    joints = [n for k in range(1, len(layout.groups)) for n in layout.column_names(k)[2:]]
    assert joints == [f"j{j}_pos{s}" for j in range(5) for s in ("", "_fb")]


def test_many_joints_spread_over_several_samplers():
    layout = standard_layout("XYZABCUVW", 9)
    names = [n for k in range(len(layout.groups)) for n in layout.column_names(k)[2:]]
    assert len(layout.groups) == 4 and len(names) == 9 + 8 + 18 and len(set(names)) == len(names)


def test_layout_rejects_overfull_sampler_and_bad_types():
    cols = tuple(Column(f"c{i}", f"p.{i}", "float") for i in range(MAX_PINS_PER_SAMPLER))
    with pytest.raises(ValueError, match="at most"):
        SamplerLayout(groups=(cols,))
    with pytest.raises(ValueError, match="unknown HAL type"):
        Column("x", "axis.x.pos-cmd", "double")


def test_recorder_tcl_gates_every_sampler_with_one_signal_closed_at_load():
    layout = standard_layout("XYZAC", 5)
    tcl = recorder_tcl(layout)
    assert f"loadrt sampler depth={layout.depth},{layout.depth} cfg={','.join(layout.cfgs)}" in tcl
    for channel in layout.channels:
        assert f"net {ENABLE_SIGNAL} sampler.{channel}.enable" in tcl
        assert f"addf sampler.{channel} servo-thread" in tcl
        assert f"sampler.{channel}.pin.0" in tcl
    assert "feedlog_link axis.c.pos-cmd sampler.0.pin.5" in tcl
    # the gate is closed before the first sampler is added to the thread
    assert tcl.index(f"sets {ENABLE_SIGNAL} 0") < tcl.index("addf sampler.")
