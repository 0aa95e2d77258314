"""The subroutine files a recorded program calls, carried in the recording beside `program.ngc`.

LinuxCNC opens `o<name> call` files along the INI's SUBROUTINE_PATH (the recorder runs the program from a
copy, so the program's own folder is not searched). The recorder attaches each file it finds there as
`subroutines/<name>.ngc` (`subroutine_attachments`), so that a recording stays readable on its own:
`load_recorded_program` interprets the attached program with those files as its search path, and the
block table's `file` column names them as `subroutines/<name>.ngc` (the main program keeps its label).
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np

from feedlog.recording import Recording

SUBROUTINE_PREFIX = "subroutines/"
# o<name> call (LinuxCNC lower-cases the name to find the file); comments may hold anything
_CALL = re.compile(rb"o\s*<\s*([^>]+?)\s*>\s*call", re.IGNORECASE)
_COMMENT = re.compile(rb"\([^)\n]*\)|;[^\n]*")


def called_names(text: bytes) -> list[str]:
    """The subroutine names `text` calls with `o<name> call`, in order of first call (lower case)."""
    seen: dict[str, None] = {}
    for m in _CALL.finditer(_COMMENT.sub(b" ", text)):
        seen.setdefault(m.group(1).decode("utf-8", "replace").replace(" ", "").lower(), None)
    return list(seen)


def subroutine_attachments(program_text: bytes, search_path: list[Path]) -> dict[str, bytes]:
    """`subroutines/<name>.ngc` -> bytes for every file along `search_path` that the program calls,
    directly or from another such file (a name the program defines itself is still looked up: LinuxCNC
    uses the definition it meets first, and the file is harmless when unused)."""
    found: dict[str, bytes] = {}
    pending = called_names(program_text)
    while pending:
        name = pending.pop(0)
        key = f"{SUBROUTINE_PREFIX}{name}.ngc"
        if key in found:
            continue
        for folder in search_path:
            path = Path(folder) / f"{name}.ngc"
            if path.is_file():
                found[key] = path.read_bytes()
                pending += [n for n in called_names(found[key]) if f"{SUBROUTINE_PREFIX}{n}.ngc" not in found]
                break
    return found


def load_recorded_program(recording: Recording, *, lenient: bool = False, dialect: str = "auto",
                          name: str | None = None):
    """The recording's attached program (`program.ngc`) read with its attached subroutine files.
    Returns None when no program is attached."""
    from feedlog.toolpath import load_program
    from feedlog.toolpath.interp import InterpOptions

    text = recording.program_text
    if text is None:
        return None
    subs = {k: v for k, v in recording.attachments.items() if k.startswith(SUBROUTINE_PREFIX)}
    if not subs:
        return load_program(text, lenient=lenient, dialect=dialect, name=name)
    with tempfile.TemporaryDirectory(prefix="feedlog-subs-") as tmp:
        folder = Path(tmp)
        for key, data in subs.items():
            (folder / Path(key).name).write_bytes(data)
        program = load_program(text, lenient=lenient, dialect=dialect, name=name,
                               interp=InterpOptions(search_path=(folder,)))
        blocks = program.blocks
        if "file" in blocks.columns:  # name the attachment, not the temporary folder
            prefix = f"{folder}/"
            files = blocks["file"].astype(str).to_numpy()
            inside = np.char.startswith(files.astype(str), prefix)
            if inside.any():
                renamed = files.copy()
                renamed[inside] = [SUBROUTINE_PREFIX + f[len(prefix):] for f in files[inside]]
                blocks["file"] = renamed
            if "stack" in blocks.columns:
                blocks["stack"] = blocks["stack"].astype(str).str.replace(prefix, SUBROUTINE_PREFIX, regex=False)
    return program


__all__ = ["SUBROUTINE_PREFIX", "called_names", "load_recorded_program", "subroutine_attachments"]
