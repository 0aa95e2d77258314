"""Where a subroutine file is looked for: LinuxCNC's interpreter opens `o<name> call` files in its current
directory and along [RS274NGC] SUBROUTINE_PATH (its INI documentation adds [DISPLAY] PROGRAM_PREFIX before
and [WIZARD] WIZARD_ROOT after; not checked here), not in the calling program's folder: `rs274 -g` run
from another directory refuses the call (found recording for issue #27: the recorder had to pass
SUBROUTINE_PATH)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from feedlog.toolpath.interp import interpret


def _program_beside_its_sub(tmp_path):
    folder = tmp_path / "prog"
    folder.mkdir()
    (folder / "mysub.ngc").write_text("o<mysub> sub\nG1 X1 F100\no<mysub> endsub\nM2\n")
    (folder / "main.ngc").write_text("G21\no<mysub> call\nM2\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    return folder / "main.ngc", elsewhere


@pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC's rs274 is not installed")
def test_linuxcnc_does_not_look_in_the_program_folder(tmp_path):
    main, elsewhere = _program_beside_its_sub(tmp_path)
    away = subprocess.run(["rs274", "-g", str(main)], cwd=elsewhere, capture_output=True, text=True,
                          stdin=subprocess.DEVNULL, timeout=30)
    assert "seeking o-word: o<mysub> from line: 2" in away.stdout + away.stderr
    assert "STRAIGHT_FEED" not in away.stdout
    here = subprocess.run(["rs274", "-g", str(main)], cwd=main.parent, capture_output=True, text=True,
                          stdin=subprocess.DEVNULL, timeout=30)
    assert "STRAIGHT_FEED" in here.stdout   # its current directory is searched


def test_feedlog_also_looks_beside_the_program_a_documented_choice(tmp_path):
    """Unlike LinuxCNC (above), feedlog searches the program's own folder first, so that a program and its
    subroutine files read together wherever they are (docs/interpreter.md says so)."""
    main, _ = _program_beside_its_sub(tmp_path)
    program = interpret(main)
    assert program.motion["x_mm"].tolist() == [1.0]
    assert str(program.motion["file"].iloc[0]).endswith("mysub.ngc")
    doc = (Path(__file__).resolve().parents[2] / "docs" / "interpreter.md").read_text()
    assert "not the program's folder" in doc
