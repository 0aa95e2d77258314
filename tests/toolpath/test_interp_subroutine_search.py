"""Where a subroutine file is looked for: LinuxCNC's interpreter opens `o<name> call` files in its current
directory and along [RS274NGC] SUBROUTINE_PATH (its INI documentation adds [DISPLAY] PROGRAM_PREFIX before
and [WIZARD] WIZARD_ROOT after; not checked here), not in the calling program's folder: `rs274 -g` run
from another directory refuses the call (found recording for issue #27: the recorder had to pass
SUBROUTINE_PATH)."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from feedlog.errors import ProgramError
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


@pytest.mark.xfail(strict=True, reason="interpreter bug: feedlog's interpreter opens o<name> call files in "
                   "the program's own folder, which LinuxCNC does not search (rs274 -g from another directory: "
                   "'seeking o-word: o<mysub> from line: 2'), so it reads a program LinuxCNC refuses on line 2; docs/interpreter.md "
                   "calls the program-folder search 'as LinuxCNC'")
def test_a_subroutine_only_beside_the_program_is_refused_as_linuxcnc_does(tmp_path):
    main, _ = _program_beside_its_sub(tmp_path)
    with pytest.raises(ProgramError) as info:
        interpret(main)
    assert info.value.line == 2

