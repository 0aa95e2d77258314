"""Output files written all or nothing: each under a fresh temporary name beside it, renamed at the end.

A disk that fills up, a file size limit or any error while writing leaves no half-written output and
no temporary file: the temporary files are removed and the error says which output failed. The
temporary name is created exclusively (O_CREAT | O_EXCL | O_NOFOLLOW), so a symlink or a file that
already sits there is never followed or overwritten; the final rename replaces a symlink at the
target, not what it points to. (The live logger is the exception by design: it writes its recording
in place, so a killed process leaves every flushed chunk readable.)
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

from feedlog.errors import OutputError

_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)


def temporary_beside(path: Path) -> Path:
    """A new, empty file next to `path` (`NAME.<random>.partial`), created exclusively."""
    for _ in range(100):
        candidate = path.with_name(f"{path.name}.{secrets.token_hex(4)}.partial")
        try:
            os.close(os.open(candidate, _FLAGS, 0o666))
        except FileExistsError:
            continue
        except OSError as exc:
            raise OutputError(f"cannot create the output: {exc.strerror or exc}", file=str(path)) from None
        return candidate
    raise OutputError("cannot find a free temporary name beside the output", file=str(path))


@contextlib.contextmanager
def atomic_outputs(*paths: str | os.PathLike) -> Iterator[list[Path]]:
    """Temporary paths to write instead of `paths`; renamed onto them when the block ends without an
    error, removed otherwise. An OSError while writing or renaming becomes `OutputError`."""
    targets = [Path(p) for p in paths]
    temporaries: list[Path] = []
    try:
        for target in targets:
            temporaries.append(temporary_beside(target))
        try:
            yield temporaries
            for temporary, target in zip(temporaries, targets):
                os.replace(temporary, target)
        except OSError as exc:
            where = targets[0] if len(targets) == 1 else targets[0].parent
            names = "" if len(targets) == 1 else f" {', '.join(t.name for t in targets)}"
            raise OutputError(f"cannot write the output{names} ({exc.strerror or exc}); nothing was written",
                              file=str(where)) from None
    finally:
        for temporary in temporaries:
            with contextlib.suppress(OSError):
                temporary.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """`atomic_outputs` for one file."""
    with atomic_outputs(path) as (temporary,):
        yield temporary
