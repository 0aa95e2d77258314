"""Progress along the program from sparse samples, and evidence from the data alone."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.diagnose.evidence import AxisEvidence, Evidence, contradicts, sustained_peak
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


def test_a_sustained_peak_ignores_a_spike():
    a = np.zeros(100)
    a[10:40] = 300.0
    a[70] = 5000.0
    assert sustained_peak(a, 8) == 300.0


def test_evidence_rules_out_a_limit_the_data_contradicts():
    ev = Evidence(axes={"z": AxisEvidence("z", "mm", peak_vel=20.0, peak_acc=1000.0, travel=10.0)},
                  path_speed_ceiling_mm_s=50.0)
    assert "never seen above" in contradicts(ev, "axes.z.acc_max", 1000.0, 2000.0)
    assert contradicts(ev, "axes.z.acc_max", 1000.0, 900.0) is None
    assert "far above" in contradicts(ev, "axes.z.vel_max", 100.0, 5.0)
    assert contradicts(ev, "axes.z.vel_max", 100.0, 20.5) is None
    assert "far above" in contradicts(ev, "interpolator.path_vel_max_mm_s", 100.0, 10.0)
