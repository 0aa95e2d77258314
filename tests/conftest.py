"""Shared test fixtures: repository paths and the LinuxCNC availability rule."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def examples_dir() -> Path:
    return ROOT / "examples"


def linuxcnc_missing_reason() -> str | None:
    """Why LinuxCNC tests cannot run here, or None when they can."""
    for tool in ("linuxcnc", "halsampler", "halcmd"):
        if shutil.which(tool) is None:
            return f"LinuxCNC is not installed ({tool} not on PATH; apt-get install linuxcnc-uspace)"
    if not Path("/usr/bin/python3").exists():
        return "Debian's /usr/bin/python3 (which carries the linuxcnc module) is missing"
    return None


def pytest_runtest_setup(item):
    if "linuxcnc" not in item.keywords:
        return
    reason = linuxcnc_missing_reason()
    if reason is None:
        return
    if os.environ.get("FEEDLOG_REQUIRE_LINUXCNC") == "1":
        pytest.fail(f"LinuxCNC is required here (FEEDLOG_REQUIRE_LINUXCNC=1): {reason}")
    pytest.skip(reason)
