"""A read-only file whose `read(n)` never asks for more than the bytes left in it.

Binary formats store lengths, and readers (the `mcap` stream reader, python-can's BLF reader) pass
them straight to `read`, where CPython allocates the full amount before the read comes back short: a
2.5 KB file claiming a 4 GiB string takes 4 GiB. Reading through this wrapper caps every such
allocation at the size of the file.
"""

from __future__ import annotations

import os


class BoundedReader:
    """`path` opened for reading, every `read` capped at the bytes left. (A plain object on purpose:
    an io.RawIOBase would be wrapped in a BufferedReader again, whose read(n) allocates n bytes.)"""

    def __init__(self, path: str | os.PathLike) -> None:
        self._f = open(path, "rb")  # noqa: SIM115 - closed with this object
        self._left = os.fstat(self._f.fileno()).st_size

    def read(self, n: int | None = -1) -> bytes:
        if n is None or n < 0 or n > self._left:
            n = self._left
        data = self._f.read(n)
        self._left -= len(data)
        return data

    def tell(self) -> int:
        return self._f.tell()

    def fileno(self) -> int:
        return self._f.fileno()

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> BoundedReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
