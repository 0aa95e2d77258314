"""Shared fixtures for the simulation tests: a plain test machine and a G-code helper."""

from __future__ import annotations

import pytest

from feedlog.profile import MachineProfile
from feedlog.toolpath import parse_program


def machine(*, vel=50.0, acc=1000.0, five_axis=False, **interp) -> MachineProfile:
    """A machine with equal limits on every axis and no controller preset."""
    axes = {a: {"vel_max": vel, "acc_max": acc} for a in ("x", "y", "z")}
    data = {"name": "test", "controller": "test rig", "rapid_mm_min": vel * 60.0,
            "axes": axes, "interpolator": {"lookahead_blocks": 50, **interp}}
    if five_axis:
        axes["a"] = {"vel_max": 60.0, "acc_max": 600.0, "min_limit": -120.0, "max_limit": 120.0}
        axes["c"] = {"vel_max": 60.0, "acc_max": 600.0}
        data["kinematics"] = {"type": "xyzac-trt"}
    return MachineProfile.from_dict(data)


def program(text: str):
    return parse_program(text, name="test.ngc")


@pytest.fixture
def plain() -> MachineProfile:
    return machine()


@pytest.fixture
def make_machine():
    return machine


@pytest.fixture
def gcode():
    return program
