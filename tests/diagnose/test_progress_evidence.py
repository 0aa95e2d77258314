"""Progress along the program from sparse samples, and evidence from the data alone."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.diagnose.evidence import AxisEvidence, Evidence, sustained_peak
from feedlog.diagnose.hypothesis import family
from feedlog.diagnose.progress import block_end_progress, crossing_times, sample_progress


def test_progress_of_samples_on_an_l_shaped_path_and_when_a_corner_was_passed():
    cl = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0]], float)
    s_cl = np.array([0.0, 10.0, 20.0])
    t_cl = np.array([0.0, 1.0, 2.0])
    t = np.array([0.0, 0.5, 0.95, 1.2, 2.0])
    pos = np.array([[0, 0, 0], [5, 0.001, 0], [9.6, 0.3, 0], [10, 2, 0], [10, 10, 0]], float)  # a cut corner
    s = sample_progress(t, pos, cl, s_cl, t_cl)
    assert s[1] == pytest.approx(5.0, abs=1e-3) and s[3] == pytest.approx(12.0, abs=1e-3)
    assert np.all(np.diff(s) >= 0)
    t_corner = crossing_times(t, s, np.array([10.0]))[0]
    assert 0.95 < t_corner < 1.2
    assert block_end_progress(np.array([1, 1, 2]), s_cl, np.array([1, 2, 9])).tolist()[:2] == [10.0, 20.0]


def test_a_sample_past_a_short_block_whose_cl_points_share_one_time_is_found_on_the_next_block():
    """CL times matched to 5 Hz samples are those samples' times: a short turn-around's points all carry
    the time of the sample after it. The sample there is already on the next line."""
    turn = np.array([[0.0, 12.5 + 2.5 * k / 20, 0.0] for k in range(21)])           # 20 CL segments of 0.125 mm
    cl = np.vstack([[[30.0, 12.5, 0.0]], turn, [[30.0, 15.0, 0.0]]])
    s_cl = np.concatenate([[0.0], 30.0 + np.linspace(0.0, 2.5, 21), [62.5]])
    t_cl = np.concatenate([[0.0], np.full(21, 4.4), [5.0]])
    t = np.array([4.2, 4.4, 4.6])
    pos = np.array([[2.0, 12.5, 0.0], [1.2, 15.0, 0.0], [11.2, 15.0, 0.0]])
    s = sample_progress(t, pos, cl, s_cl, t_cl)
    assert s[1] == pytest.approx(32.5 + 1.2, abs=1e-6)   # on the line after the turn, not inside the turn


def test_the_shipped_profile_leaves_no_timing_residual_on_its_own_5_hz_recordings(hidden):
    """A perfect model is measured the way the recording was: at 5 Hz its segment residuals are only the
    2 um noise's (before: -0.102 / +0.102 s on the pocket program)."""
    from feedlog.diagnose.engine import load_cases
    from feedlog.diagnose.fit import Scorer

    prof, cases = load_cases(hidden("control_5hz", rate_hz=5.0), "linuxcnc-xyz")
    residuals = Scorer(prof, cases, "timing").residuals({})
    assert all(r is not None and np.abs(r).max() < 0.005 for r in residuals), residuals


def test_a_sustained_peak_ignores_a_spike():
    a = np.zeros(100)
    a[10:40] = 300.0
    a[70] = 5000.0
    assert sustained_peak(a, 8) == 300.0


def test_evidence_rules_out_a_limit_the_data_contradicts():
    ev = Evidence(axes={"z": AxisEvidence("z", "mm", peak_vel=20.0, peak_acc=1000.0, travel=10.0)},
                  path_speed_ceiling_mm_s=50.0)
    assert "never seen above" in family("axis_limits").contradicts(ev, "axes.z.acc_max", 1000.0, 2000.0)
    assert family("axis_limits").contradicts(ev, "axes.z.acc_max", 1000.0, 900.0) is None
    assert "far above" in family("axis_limits").contradicts(ev, "axes.z.vel_max", 100.0, 5.0)
    assert family("axis_limits").contradicts(ev, "axes.z.vel_max", 100.0, 20.5) is None
    assert "far above" in family("path_limits").contradicts(ev, "interpolator.path_vel_max_mm_s", 100.0, 10.0)
