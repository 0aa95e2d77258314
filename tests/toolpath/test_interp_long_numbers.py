"""Numbers too long for any machine in the interpreter's words: one clear error naming the line, as the
vectorised parser gives (found by the fuzz corpus once load_program let the interpreter read what the
parser refuses)."""

from __future__ import annotations

import pytest

from feedlog.errors import ProgramError
from feedlog.toolpath.interp import interpret


def test_a_400_digit_n_word_is_one_clear_error():
    with pytest.raises(ProgramError) as info:
        interpret("#1 = 1\nN" + "9" * 400 + " G1 X#1 F100\nM2\n", name="t.ngc")
    assert info.value.line == 2
