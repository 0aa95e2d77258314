"""Where inputs and outputs live: local paths or fsspec URLs, and outputs that appear whole or not at all.

A location is a path (made absolute on the client, so that a worker in another directory or on another
host finds the same file) or an fsspec URL (`file:///data/rec.mcap`, `s3://bucket/aligned`; `s3://`
etc. need the user's filesystem package, e.g. s3fs). `file://` URLs become plain absolute paths.

Outputs are written under a temporary name beside their target (`.NAME.partial-TOKEN...`, which
pyarrow, dask, pandas and duckdb skip) and renamed into place when complete (`publish_dir`,
`publish_file`): a task killed midway leaves no half-written output, only a partial that
`remove_partials` clears. On object stores the "rename" is fsspec's move (copy, then delete).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from feedlog.errors import FeedlogError, OutputError

PARTIAL = ".partial-"


def is_url(location: str | os.PathLike) -> bool:
    return "://" in str(location)


def absolute(location: str | os.PathLike) -> str:
    """An absolute local path, or the URL unchanged (`file://` URLs become paths)."""
    text = str(location)
    if text.startswith("file://"):
        text = text[len("file://"):]
    elif is_url(text):
        return text
    return os.path.abspath(os.path.expanduser(text))


def stem(location: str | os.PathLike) -> str:
    """The file name without its suffix, for paths and URLs alike."""
    return Path(str(location).rstrip("/").rsplit("/", 1)[-1]).stem


def join(root: str, *parts: str) -> str:
    return "/".join([root.rstrip("/"), *parts]) if is_url(root) else str(Path(root, *parts))


def _fs(url: str):
    try:
        import fsspec  # only for URLs
    except ImportError:
        raise FeedlogError(f"{url}: URLs need fsspec (pip install fsspec)") from None
    try:
        return fsspec.core.url_to_fs(url)
    except (ImportError, ValueError) as exc:
        raise FeedlogError(f"{url}: no filesystem for this URL ({exc}); install the fsspec package for its "
                           "scheme (s3fs, gcsfs, adlfs, ...)") from None


def exists(location: str) -> bool:
    if not is_url(location):
        return os.path.exists(location)
    fs, path = _fs(location)
    return fs.exists(path)


@contextmanager
def local_input(location: str) -> Iterator[Path]:
    """A local file holding `location`: the path itself, or a temporary download of the URL."""
    if not is_url(location):
        yield Path(location)
        return
    fs, path = _fs(location)
    if not fs.exists(path):
        raise FeedlogError(f"{location}: no such file")
    with tempfile.TemporaryDirectory(prefix="feedlog-in-") as tmp:
        local = Path(tmp) / Path(path).name
        fs.get_file(path, str(local))
        yield local


def read_text(location: str) -> str:
    if not is_url(location):
        return Path(location).read_text()
    fs, path = _fs(location)
    with fs.open(path, "rt") as f:
        return f.read()


def writable_dir(location: str | os.PathLike) -> None:
    """Make sure the output folder `location` exists and takes files, before any work is done: a file
    where the folder goes, a read-only or full file system end in one `OutputError` here instead of a
    failure per task (or a traceback) later. URLs are left to their filesystem."""
    text = str(location)
    if is_url(text):
        return
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise OutputError("exists and is not a folder; give an output folder", file=text)
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".feedlog-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"cannot write into this folder ({exc.strerror or exc}); nothing was written",
                          file=text) from None


def _partial_name(target: str, token: str) -> str:
    parent, _, name = target.rstrip("/").rpartition("/") if is_url(target) else (
        str(Path(target).parent), "", Path(target).name)
    return join(parent, f".{name}{PARTIAL}{token}-{uuid.uuid4().hex[:8]}")


@contextmanager
def _as_output_error(target: str) -> Iterator[None]:
    """An OSError while writing `target` (full disk, read-only file system) as one `OutputError`."""
    try:
        yield
    except OSError as exc:
        raise OutputError(f"cannot write the output ({exc.strerror or exc}); nothing was written",
                          file=target) from None


@contextmanager
def publish_dir(target: str, *, token: str = "") -> Iterator[Path]:
    """A local folder to fill; on success it replaces `target` (a folder) in one rename, else it is removed."""
    if not is_url(target):
        staging = Path(_partial_name(target, token))
        with _as_output_error(target):
            staging.mkdir(parents=True)
        try:
            yield staging
            with _as_output_error(target):
                old = Path(_partial_name(target, token)) if os.path.exists(target) else None
                if old is not None:
                    os.rename(target, old)  # the previous output stays whole until the new one is in place
                os.rename(staging, target)
                if old is not None:
                    shutil.rmtree(old)
        finally:
            if staging.exists():
                shutil.rmtree(staging)
        return
    fs, path = _fs(target)
    with tempfile.TemporaryDirectory(prefix="feedlog-out-") as tmp:
        yield Path(tmp)
        remote = _fs(_partial_name(target, token))[1]
        fs.put(tmp + "/", remote, recursive=True)
        if fs.exists(path):
            fs.rm(path, recursive=True)
        fs.mv(remote, path, recursive=True)


def publish_file(target: str, write: Callable[[Path], None], *, token: str = "") -> None:
    """`write(local_path)` then move the file into place as `target` (replacing it)."""
    if not is_url(target):
        staging = Path(_partial_name(target, token))
        try:
            with _as_output_error(target):
                Path(target).parent.mkdir(parents=True, exist_ok=True)
                write(staging)
                os.replace(staging, target)
        finally:
            with suppress(OSError):
                staging.unlink(missing_ok=True)
        return
    fs, path = _fs(target)
    with tempfile.TemporaryDirectory(prefix="feedlog-out-") as tmp:
        local = Path(tmp) / "part"
        write(local)
        remote = _fs(_partial_name(target, token))[1]
        fs.makedirs(fs._parent(path), exist_ok=True)
        fs.put_file(str(local), remote)
        fs.mv(remote, path)


def remove_partials(root: str, token: str, *, depth: int = 4) -> int:
    """Remove what tasks of job `token` left half-written under `root` (workers killed midway); count."""
    if not token or not exists(root):
        return 0
    if is_url(root):
        fs, path = _fs(root)
        found = [p for p in fs.find(path, maxdepth=depth, withdirs=True) if f"{PARTIAL}{token}" in p.rsplit("/", 1)[-1]]
        for p in found:
            if fs.exists(p):
                fs.rm(p, recursive=True)
        return len(found)
    count = 0
    for dirpath, dirnames, filenames in os.walk(root):
        if dirpath[len(root):].count(os.sep) >= depth:
            dirnames[:] = []
        for name in [*dirnames, *filenames]:
            if f"{PARTIAL}{token}" in name:
                full = os.path.join(dirpath, name)
                shutil.rmtree(full) if os.path.isdir(full) else os.unlink(full)
                count += 1
        dirnames[:] = [d for d in dirnames if f"{PARTIAL}{token}" not in d]
    return count
