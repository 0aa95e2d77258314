"""A part program's text as the parser wants it: from a file or a string, line ends made "\n".

Programs come from CAM posts, editors and controllers: a UTF-8 BOM is skipped, CR LF (Windows) and a
lone CR (old Mac files) count as line ends, as editors show them, and a UTF-16 file is refused with a
message that says so instead of a wall of "unsupported character" errors. Bytes that are not UTF-8
(latin-1 comments) become U+FFFD, which only comments may hold.
"""

from __future__ import annotations

from pathlib import Path

from feedlog.errors import ProgramError


def _looks_like_path(source: str) -> bool:
    """One short line naming a program file (by suffix, or an existing file), not G-code text."""
    if "\n" in source or "\r" in source or len(source) >= 4096:
        return False
    if Path(source).suffix.lower() in (".ngc", ".nc", ".gcode", ".tap", ".txt", ".cnc"):
        return True
    try:
        return Path(source).is_file()
    except (OSError, ValueError):  # too long for a file name, a NUL byte: text
        return False


def read_source(source: str | Path, name: str | None) -> tuple[str, Path | None, str]:
    """(text with "\n" line ends, path or None, name for messages). Old Mac files end lines with a
    lone CR and Windows files with CR LF: both count as line ends, as editors show them."""
    if isinstance(source, Path) or _looks_like_path(source):
        path = Path(source)
        label = name or str(path)
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise ProgramError(f"cannot read part program: {exc.strerror or exc}", file=label) from None
        if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
            raise ProgramError("the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save the "
                               "part program as ASCII or UTF-8", file=label, line=1)
        text, path_out = raw.decode("utf-8-sig", errors="replace"), path
    else:
        text, path_out, label = source.removeprefix("\ufeff"), None, name or "<string>"
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text, path_out, label
