"""A part program's text as the parser wants it: from a file or a string, line ends made "\n".

Programs come from CAM posts, editors and controllers: a UTF-8 BOM is skipped, CR LF (Windows) and a
lone CR (old Mac files) count as line ends, as editors show them, and a UTF-16 file is refused with a
message that says so instead of a wall of "unsupported character" errors, and so is a binary file (a NUL
byte in its first 8 KiB: a recording given as the program). Bytes that are not UTF-8
(latin-1 comments) become U+FFFD, which only comments may hold.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from feedlog.errors import ProgramError

CHUNK_BYTES = 4 << 20  # text parsed at once: ~110k lines of CAM output, ~150 MB of parser temporaries


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


def _refuse_binary(head: bytes, label: str) -> None:
    """Text never holds a NUL byte; a recording, an archive or an image given as the program does."""
    nul = head.find(b"\0", 0, 8192)
    if nul >= 0:
        what = " (an MCAP file: a recording?)" if head.startswith(b"\x89MCAP") else ""
        raise ProgramError(f"not a text part program: the file holds binary data, a NUL byte here{what}",
                           file=label, line=head.count(b"\n", 0, nul) + 1)


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
        _refuse_binary(raw, label)
        text, path_out = raw.decode("utf-8-sig", errors="replace"), path
    else:
        text, path_out, label = source.removeprefix("\ufeff"), None, name or "<string>"
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text, path_out, label


def _line_ends(text: str) -> str:
    return text.replace("\r\n", "\n").replace("\r", "\n") if "\r" in text else text


def _cut(buf: bytes | str, final: bool) -> int:
    """End of the last complete line in `buf` (after its line end), 0 when none is complete yet. A CR at
    the very end may be the first half of a CR LF, so it waits for the next read."""
    if final:
        return len(buf)
    lf = buf.rfind(b"\n" if isinstance(buf, bytes) else "\n")
    cr = buf.rfind(b"\r" if isinstance(buf, bytes) else "\r", 0, len(buf) - 1)
    return max(lf, cr) + 1


def open_source(source: str | Path, name: str | None, *, chunk_bytes: int = CHUNK_BYTES
                ) -> tuple[Path | None, str, Iterator[str]]:
    """(path or None, name for messages, chunks): the program's text in pieces of whole lines of about
    `chunk_bytes`, line ends made "\n", as `read_source` would give it at once. A file is read as the
    chunks are taken, so its size does not matter."""
    if not (isinstance(source, Path) or _looks_like_path(source)):
        text, _, label = read_source(source, name)
        return None, label, _text_chunks(text, chunk_bytes)
    path = Path(source)
    label = name or str(path)
    try:
        handle = path.open("rb")
    except OSError as exc:
        raise ProgramError(f"cannot read part program: {exc.strerror or exc}", file=label) from None
    return path, label, _file_chunks(handle, label, chunk_bytes)


def _text_chunks(text: str, chunk_bytes: int) -> Iterator[str]:
    start = 0
    while True:
        end = min(start + chunk_bytes, len(text))
        if end < len(text):
            cut = text.rfind("\n", start, end) + 1
            end = cut if cut > start else (text.find("\n", end) + 1 or len(text))
        yield text[start:end]
        if end >= len(text):
            return
        start = end


def _file_chunks(handle, label: str, chunk_bytes: int) -> Iterator[str]:
    with handle:
        carry = b""
        first = True
        while True:
            try:
                data = handle.read(chunk_bytes)
            except OSError as exc:
                raise ProgramError(f"cannot read part program: {exc.strerror or exc}", file=label) from None
            final = not data
            buf = carry + data
            if first:
                if len(buf) < 3 and not final:
                    carry = buf
                    continue
                if buf.startswith((b"\xff\xfe", b"\xfe\xff")):
                    raise ProgramError("the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save "
                                       "the part program as ASCII or UTF-8", file=label, line=1)
                _refuse_binary(buf, label)
                buf = buf.removeprefix(b"\xef\xbb\xbf")
            cut = _cut(buf, final)
            if cut == 0 and not final:
                carry = buf
                continue
            if cut or first:
                yield _line_ends(buf[:cut].decode("utf-8", errors="replace"))
            first = False
            carry = buf[cut:]
            if final:
                return
