"""Parameters as LinuxCNC keeps them: numbered #1-#5601, named locals per call level, named globals.

- `#1`-`#30` are a subroutine's arguments: saved on a call, set from the call's arguments, restored on
  return. `#31`-`#5000` are global. `#5161`-`#5390` hold G28/G30 homes, the G92 offset and the nine
  coordinate systems in machine units (mm here): they are what G10/G92/G54 read and write, and what a
  parameter file (`.var`) sets. `#5400`-`#5413` (tool) and `#5420`-`#5428` (position) are read-only.
- `#<name>` is local to the call level that set it; `#<_name>` is global. Reading a named parameter
  that was never set is an error; predefined read-only names (`#<_x>`, `#<_feed>`, ...) come from the
  interpreter's state (`Parameters.lookup`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

from feedlog.errors import ProgramError
from feedlog.toolpath.interp.errors import InterpError

MAX_PARAMETERS = 5602
READ_ONLY = frozenset(range(5400, 5414)) | frozenset(range(5420, 5429))
PERSISTENT = frozenset(list(range(5161, 5170)) + list(range(5181, 5190)) + list(range(5210, 5221))
                       + [i for s in range(1, 10) for i in range(5201 + 20 * s, 5211 + 20 * s)])


class Parameters:
    """Numbered and named parameters, with the call frames' scopes. `lookup(name)` gives predefined
    read-only named values (None when the name is not predefined)."""

    def __init__(self, lookup: Callable[[str], float | None]) -> None:
        self.p = [0.0] * MAX_PARAMETERS
        self.p[5220] = 1.0           # G54 selected until a parameter file says otherwise
        self.frames: list[dict[str, float]] = [{}]   # level 0 holds globals and the main program's locals
        self.lookup = lookup
        self.loaded = False        # a parameter file gave the work offsets

    # -- reading (the compiled expressions call these) -------------------------------------------
    def numbered(self, index: float) -> float:
        i = _index(index)
        return self.p[i]

    def named(self, name: str) -> float:
        frame = self.frames[0] if name.startswith("_") else self.frames[-1]
        value = frame.get(name)
        if value is not None:
            return value
        if name.startswith("_"):
            pre = self.lookup(name)
            if pre is not None:
                return pre
        raise InterpError(f"named parameter #<{name}> not defined")

    def exists(self, name: str) -> float:
        frame = self.frames[0] if name.startswith("_") else self.frames[-1]
        return 1.0 if name in frame or (name.startswith("_") and self.lookup(name) is not None) else 0.0

    # -- writing -------------------------------------------------------------------------------------
    def set_numbered(self, index: float, value: float) -> None:
        i = _index(index)
        if i in READ_ONLY:
            raise InterpError(f"parameter #{i} is read-only")
        self.p[i] = value

    def set_named(self, name: str, value: float) -> None:
        if name.startswith("_"):
            if self.lookup(name) is not None:
                raise InterpError(f"parameter #<{name}> is read-only")
            self.frames[0][name] = value
        else:
            self.frames[-1][name] = value

    def push(self, args: list[float]) -> list[float]:
        """A call: #1-#30 take the arguments (the rest 0); returns the saved values."""
        saved = self.p[1:31]
        self.p[1:31] = list(args) + [0.0] * (30 - len(args))
        self.frames.append({})
        return saved

    def pop(self, saved: list[float]) -> None:
        self.p[1:31] = saved
        self.frames.pop()

    @property
    def level(self) -> int:
        return len(self.frames) - 1

    # -- the parameter file -------------------------------------------------------------------------
    def load_var(self, path: str | Path) -> None:
        """LinuxCNC's parameter file: lines of `number value` in ascending order; other lines are skipped."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise ProgramError(f"cannot read parameter file: {exc.strerror or exc}", file=str(path)) from None
        last = 0
        for number, raw in enumerate(text.splitlines(), start=1):
            parts = raw.split()
            if len(parts) != 2:
                continue
            try:
                index, value = int(parts[0]), float(parts[1])
            except ValueError:
                continue
            if not (1 <= index < MAX_PARAMETERS) or not math.isfinite(value):
                raise ProgramError(f"parameter {parts[0]} = {parts[1]} out of range", file=str(path), line=number)
            if index <= last:
                raise ProgramError("parameter file out of order", file=str(path), line=number)
            last = index
            self.p[index] = value
        self.loaded = True


def _index(index: float) -> int:
    n = math.floor(index)
    if index - n > 0.9999:
        n = math.ceil(index)
    elif index - n > 0.0001:
        raise InterpError("non-integer value for parameter number")
    if not 1 <= n < MAX_PARAMETERS:
        raise InterpError(f"parameter number {n} out of range (1-{MAX_PARAMETERS - 1})")
    return int(n)
