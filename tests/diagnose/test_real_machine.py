"""A machine feedlog has no profile for gets a fitted one: three UMich-like experiments of one mill
(tests/fixtures/ingest/real, written by scripts/make_real_fixtures.py on a machine with rapids at
6000 mm/min and 800 mm/s^2 per axis) imported from CSV and diagnosed from the generic starting profile."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from feedlog.cli import main
from feedlog.profile import load_profile

REAL = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"
EXPERIMENTS = (("umich_experiment.csv", "umich_part.nc"), ("umich_experiment_02.csv", "umich_part_02.nc"),
               ("umich_experiment_03.csv", "umich_part_03.nc"))
RAPID_MM_S = 6000.0 / 60.0   # the machine's truth (make_real_fixtures.umich)
ACC_MM_S2 = 800.0


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("umich")
    recordings = []
    for k, (log, program) in enumerate(EXPERIMENTS):
        out = tmp / f"exp{k}.mcap"
        assert main(["import", str(REAL / log), "--preset", "umich-tool-wear", "--program", str(REAL / program),
                     "-o", str(out)]) == 0
        recordings.append(str(out))
    return tmp, main(["diagnose", *recordings, "--profile", "generic-xyz", "-o", str(tmp / "dx"), "--no-rrd",
                      "--no-learned", "-q"])


def test_the_generic_profile_is_fitted_to_the_machine(diagnosed, capsys):
    tmp, code = diagnosed
    assert code == 0
    report = json.loads((tmp / "dx" / "diagnose.json").read_text())
    assert report["error_before_pct"] < -10                    # the guess: rapids and corners far too fast
    assert abs(report["error_after_pct"]) < 0.5
    found = {f["parameter"]: f["fitted_value"] for f in report["findings"]}
    # the rapid rate: a rapid override of the profile's 15 m/min or a path speed cap (the feeds stay below it)
    generic = load_profile("generic-xyz")
    rapid = [generic.rapid_mm_min / 60.0 * v for k, v in found.items() if k == "sim.rapid_override.override"]
    rapid += [v for k, v in found.items() if k == "interpolator.path_vel_max_mm_s"]
    assert len(rapid) == 1 and rapid[0] == pytest.approx(RAPID_MM_S, rel=0.05), found
    # the acceleration: every axis has 800 on this machine (one path acceleration, or an axis's)
    acc = [v for k, v in found.items() if k.endswith("acc_max") or k.endswith("acc_max_mm_s2")]
    assert acc and all(v == pytest.approx(ACC_MM_S2, rel=0.15) for v in acc), found
    # held out: each experiment is predicted by values fitted on the other two
    assert all(abs(r["error_after_pct"]) < 1 for r in report["held_out"]["recordings"]), report["held_out"]


def test_the_fitted_profile_is_a_profile_the_other_commands_take(diagnosed, tmp_path):
    tmp, _ = diagnosed
    fitted = load_profile(tmp / "dx" / "profile.toml")
    assert fitted.name == "generic-xyz-diagnosed"
    out = tmp_path / "sim.parquet"
    assert main(["sim", str(REAL / "umich_part_03.nc"), "--profile", str(tmp / "dx" / "profile.toml"),
                 "-o", str(out)]) == 0
    assert out.exists()


def test_a_recording_of_part_of_a_program_is_compared_with_that_part(tmp_path):
    """The Mazak-like log holds the finishing pass only, and begins inside line 9: the simulation runs
    lines 10-20 and the comparison starts where line 9 ends (the whole program took twice as long)."""
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.ingest.readers import ImportOptions, read_source

    rec = read_source(REAL / "mazak_streams.xml", ImportOptions())
    dx = diagnose([rec], "generic-xyz", program=REAL / "mazak_part.nc",
                  config=DiagnoseConfig(learned=False))
    case = dx.cases[0]
    assert case.program.blocks["line"].min() == 10 and case.program.blocks["line"].max() <= 20
    assert case.block_end_s.index.isin(case.alignment.blocks["block"]).all()
    motion = case.alignment.report["motion"]
    assert case.t0_ns == motion["t_start_ns"] and 9.0 < case.cycle_s < 10.8   # 10.86 s recorded, 0.2 s in line 9
    assert any("line 9 was under way" in n for n in case.notes)
    assert abs(dx.levels["cycle"]["error_before_pct"]) < 3


def test_moving_samples_bound_motion_from_rest_or_else_from_the_program_ends():
    import numpy as np
    import pandas as pd

    from feedlog.diagnose.cases import moving_samples

    t = np.arange(8) * 200_000_000
    x = np.array([0.0, 0.0, 3.0, 9.0, 15.0, 17.0, 18.0, 18.0])
    axes = pd.DataFrame({"t_ns": t, "x_mm": x, "y_mm": 0.0, "z_mm": 0.0})
    start, stop = moving_samples(axes, t0_ns=300_000_000, cycle_s=0.8)   # motion 0.3 .. 1.1 s
    assert start == pytest.approx((0.1, 3.0)) and stop == pytest.approx((0.7, 1.0))
    # ends in motion (the last sample is the motion end): no bound on that side without the program's end
    start, stop = moving_samples(axes.iloc[:5], t0_ns=300_000_000, cycle_s=0.5)
    assert start == pytest.approx((0.1, 3.0)) and stop is None
    # ... and from the program's last point (machine frame) with it; the rest sample wins where there is one
    start, stop = moving_samples(axes.iloc[:5], t0_ns=300_000_000, cycle_s=0.5, start_xyz=np.array([-5.0, 0, 0]),
                                 end_xyz=np.array([18.0, 0.0, 0.0]))
    assert start == pytest.approx((0.1, 3.0)) and stop == pytest.approx((0.3, 9.0))


def test_the_machine_s_true_values_leave_no_timing_residual_at_10_hz(tmp_path):
    """Measured like the recording, phased on its first moving sample: the machine the UMich-like
    experiments were made on (rapids 6 m/min, 800 mm/s^2 per axis) explains them to the millisecond,
    though align placed their motion starts with the generic guess (before: up to 44 ms per segment)."""
    import numpy as np

    from feedlog.diagnose.engine import load_cases
    from feedlog.diagnose.fit import Scorer
    from feedlog.ingest.readers import ImportOptions, read_source
    from feedlog.ingest.cli_import import attach_session

    recordings = []
    for log, program in EXPERIMENTS:
        rec = read_source(REAL / log, ImportOptions(preset="umich-tool-wear"))
        attach_session(rec, program=str(REAL / program))
        recordings.append(rec)
    prof, cases = load_cases(recordings, "generic-xyz")
    truth = {"sim.rapid_override.override": 0.4, **{f"axes.{a}.acc_max": ACC_MM_S2 for a in "xyz"}}
    residuals = Scorer(prof, cases, "timing").residuals(truth)
    assert all(r is not None and np.abs(r).max() < 0.003 for r in residuals), residuals
