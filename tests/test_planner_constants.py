"""Planner constants come from the profile's sim mechanisms everywhere: a profile that changes one (as
`feedlog diagnose` may when it extends a profile) changes the simulation, align's block boundaries and
the learners' kinematic base time together, and the bundled profiles give what the mechanisms' defaults
give."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feedlog.align import align_recording
from feedlog.ingest import read_recording
from feedlog.profile import MachineProfile, load_profile, shipped_profiles
from feedlog.sim import simulate
from feedlog.toolpath import block_features, load_program
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import with_program_columns
from feedlog.train.kinematic import planner_constants
from feedlog.train.registry import make_model

RECORDING = Path(__file__).resolve().parent.parent / "recordings" / "mixdense_000.mcap"  # short blocks, 1 kHz


def _changed(profile: MachineProfile, mechanism: str, **params: float) -> MachineProfile:
    sim = {name: dict(table) for name, table in profile.sim.items()}
    sim.setdefault(mechanism, {}).update(params)
    return profile.replace(sim=sim)


def _table(program, profile: MachineProfile | None) -> ProgramTable:
    return ProgramTable("p", with_program_columns(block_features(program, profile), program, profile), profile=profile)


def _kinematic_base(program, profile: MachineProfile) -> np.ndarray:
    """The base time a learner multiplies (as `feedlog train` and `feedlog predict` compute it)."""
    return make_model("bilstm-final", base="kinematic").base_time(_table(program, profile))


@pytest.fixture(scope="module")
def session():
    rec = read_recording(RECORDING)
    return rec, load_program(rec.program_text), load_profile("linuxcnc-xyz")


def test_the_gap_cycles_of_the_profile_move_sim_align_and_the_base_time_together(session):
    rec, program, base = session
    changed = _changed(base, "blend_arc", gap_cycles=40.0)  # LinuxCNC's ARC_BLEND_GAP_CYCLES is 4
    assert simulate(program, changed).cycle_time_s > simulate(program, base).cycle_time_s
    before = align_recording(rec, profile=base).geometry_blocks["t_end_ns"].to_numpy()
    after = align_recording(rec, profile=changed).geometry_blocks["t_end_ns"].to_numpy()
    assert len(before) == len(after) and (before != after).any()  # more straight rests consumed by blends
    kin_before, kin_after = _kinematic_base(program, base), _kinematic_base(program, changed)
    assert kin_after.sum() > kin_before.sum()  # consumed rests ride with the slower arc, as in the sim


def test_the_segment_cycles_of_the_profile_move_sim_and_the_base_time_together(session):
    _, program, base = session
    changed = _changed(base, "lookahead", min_piece_cycles=3.0)  # TP_MIN_SEGMENT_CYCLES is 1.02
    assert simulate(program, changed).cycle_time_s > simulate(program, base).cycle_time_s
    assert _kinematic_base(program, changed).sum() > _kinematic_base(program, base).sum()


def test_a_learner_reads_the_planner_constants_of_the_tables_profile(session):
    _, program, base = session
    changed = _changed(base, "blend_arc", kink_ratio=0.05, gap_cycles=6.0)
    constants = make_model("mlp").table_constants(_table(program, changed))
    assert (constants["kink_ratio"], constants["gap_cycles"]) == (0.05, 6.0)
    assert constants["min_segment_cycles"] == planner_constants(None).min_segment_cycles


@pytest.mark.parametrize("name", shipped_profiles())
def test_the_shipped_profiles_keep_the_mechanisms_planner_constants(name):
    assert planner_constants(load_profile(name)) == planner_constants(None)
