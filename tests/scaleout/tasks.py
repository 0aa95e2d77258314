"""Task functions for the execution tests (module level: workers unpickle them)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from feedlog.errors import FeedlogError


def square(item: int) -> int:
    """Negative numbers are bad input (our error); 13 is a bug."""
    if item < 0:
        raise FeedlogError(f"item {item} is negative")
    if item == 13:
        raise ValueError("unlucky")
    return item * item


def die_once(item: tuple[str, int]) -> int:
    """The worker process dies the first time it meets value 2 (a marker file remembers)."""
    marker, value = item
    if value == 2 and not Path(marker).exists():
        Path(marker).write_text("died")
        os._exit(1)
    return value * 10


def die_always(item: int) -> int:
    if item == 2:
        os._exit(1)
    return item * 10


def slow_or_die(item: int) -> int:
    """Value 2 kills its worker process after a while; the others take as long (so one runs beside it)."""
    time.sleep(0.3)
    if item == 2:
        os._exit(1)
    return item * 10
