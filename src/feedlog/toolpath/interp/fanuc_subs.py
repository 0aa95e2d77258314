"""Fanuc-style subprograms inside RS274/NGC files, as LinuxCNC 2.9 reads them.

LinuxCNC (unless its INI sets DISABLE_FANUC_STYLE_SUB) reads a line that starts (after an optional `/`
and N number) with `M98 P<n> [L<k>]` as a call of the subprogram `O<n>`, and one that starts with `M99`
inside such a call as its return:

- the subprogram is a bare `O<n>` line (nothing after it but comments) whose body runs to `M99`; it is
  found where LinuxCNC finds it: a definition met before, else the file `<n>.ngc` along the search path,
  else further down the file being read (so subprograms after the main program's M2/M30 are found);
- `L<k>` calls it k times (`L0`: not at all; a negative L once); #1-#30 are not touched (the
  subprogram sees and may change the caller's), named local parameters are its own;
- an `O<n>` line met by the main program itself is run through (a program number);
- `M99` in the main program ends the program here (LinuxCNC's task starts it again, endlessly: feedlog
  ends it with a warning, as its Fanuc front-end does);
- mixing the two styles is LinuxCNC's error: `M98` to an `o<n> sub`, `o<n> call` to a bare `O<n>`,
  `M99` ending an `o<n> sub`, `endsub`/`return` ending a bare `O<n>`; `M98`/`M99` after other words on
  a line are errors too (an `M99` after words in the main program ends it, like M2).
"""

from __future__ import annotations

import math

from feedlog.toolpath.interp.block import build, enhance
from feedlog.toolpath.interp.errors import InterpError


def control(it, line) -> bool:
    """Run an `M98` / `M99` line on interpreter `it` (runner.Interpreter); True when it ends the program."""
    ow = line.oword
    P = it.params
    if ow.kind == "m98":
        if it.skipping is not None or it.skipping_to_sub is not None or it.defining_sub:
            return False
        p_word, l_word = (a(P) if callable(a) else a for a in ow.args)
        n = math.floor(p_word)
        if p_word - n > 0.9999:
            n = math.ceil(p_word)
        elif p_word - n > 0.0001:
            raise InterpError(f"non-integer value for integer: M98 P{p_word:g}")
        calls = 1 if l_word is None else int(math.floor(l_word + 0.5))
        if calls == 0:
            return False
        enter(it, str(n), max(calls, 1) - 1)
        return False
    # M99
    if len(it.frames) == 1:
        if it.skipping is not None or it.skipping_to_sub is not None:
            return False
        b = build([("m", 99.0)], P)
        enhance(b, it.m.motion_mode, it.m.plane)
        it._record(line, b.m_list)
        it.m.execute(b)
        it.metadata.setdefault("end_line", it.seq)
        it.warnings.append(f"M99 in the main program (line {it.seq}) ends it here; LinuxCNC would start the "
                           "program again, endlessly")
        return True
    frame = it.frames[-1]
    if it.skipping_to_sub is not None:
        return False
    if it.defining_sub:
        raise InterpError("found 'M99' instead of 'O endsub' after 'O sub'")
    if it.skipping is not None and it.skipping != frame.name:
        return False
    if frame.kind != "m98":
        raise InterpError("'O.... endsub' or 'O.... return' must follow 'O.... sub' (M99 ends only "
                          "Fanuc-style 'O....' subprograms)")
    it.frames.pop()
    it._stack_key = -1
    P.frames.pop()
    it.skipping = None
    it.return_value, it.value_returned = 0.0, 0.0
    it.file, it.index, it.seq = frame.ret_file, frame.ret_index, frame.call_line
    if frame.repeats > 0:
        enter(it, frame.name, frame.repeats - 1)
    return False


def enter(it, name: str, repeats: int) -> None:
    """Call subprogram `name` (then `repeats` more times): a new frame, then to its O line."""
    from feedlog.toolpath.interp.runner import MAX_CALL_LEVEL, Frame

    if len(it.frames) >= MAX_CALL_LEVEL:
        raise InterpError(f"too many nested subroutine calls (LinuxCNC allows {MAX_CALL_LEVEL - 1})")
    label = it._label(name)
    if label is not None and label.kind == "sub":
        raise InterpError(f"'O.... sub' subroutine must be called with 'O.... call' (M98 P{name} to o{name} sub)")
    it.frames.append(Frame(name=name, ret_file=it.file, ret_index=it.index, call_line=it.seq, kind="m98",
                           repeats=repeats))
    it.params.frames.append({})
    it._stack_key = -1
    it.value_returned = 0.0
    if label is not None:
        it._back_to(label)
        return
    sub = it._find_sub_file(name)
    if sub is not None:
        it.file, it.index = sub, 0
    it.skipping = name            # else LinuxCNC looks further down the file it is reading
    it.skipping_to_sub = name


def check_definition(it, kind: str) -> None:
    """At an `O<n>` (kind "") or `o<n> sub` line: the style of the call that arrived there must match."""
    if len(it.frames) == 1 or (it.skipping is not None and it.skipping != it.frames[-1].name):
        return
    caller = it.frames[-1]
    if kind == "" and caller.kind != "m98":
        it.file, it.seq = caller.ret_file, caller.call_line      # LinuxCNC names the call's line
        raise InterpError("Fanuc-style 'O....' subprogram must be called with 'M98'")
    if kind == "sub" and caller.kind == "m98":
        it.file, it.seq = caller.ret_file, caller.call_line
        raise InterpError("'O.... sub' subroutine must be called with 'O.... call', not M98")


def check_m99_in_line(it) -> None:
    """An M99 after other words on a line: the main program's end; inside a subprogram LinuxCNC's error."""
    if len(it.frames) > 1:
        raise InterpError("M99 returns from a subprogram only at the start of its line")
