"""Named entries of one kind (models, shipped profiles, ...): add one, look one up, list them.

`Registry("model", error=ModelError, load=...)` keeps entries in the order they were added. `load`
fills it on first use (built-ins register themselves when their modules are imported, or are found
on disk); an unknown name raises the registry's error listing the names it knows; a name added twice
with a different entry is refused. `unknown_name` is the one wording of that error, for the string
registries of `feedlog.lazy` too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Generic, TypeVar

from feedlog.errors import FeedlogError

T = TypeVar("T")


def unknown_name(what: str, name: str, known: Iterable[str], *, error: type[FeedlogError] = FeedlogError,
                 known_word: str = "known", hint: str = "") -> FeedlogError:
    """The error for a name no registry entry has: `unknown model 'x'; known: a, b`."""
    return error(f"unknown {what} {name!r}; {known_word}: {', '.join(known)}{hint}")


class Registry(Generic[T]):
    """Entries by name, in the order added; filled by `load` on first use."""

    def __init__(self, what: str, *, error: type[FeedlogError] = FeedlogError,
                 load: Callable[[Registry[T]], None] | None = None, known_word: str = "known", hint: str = "") -> None:
        self.what, self.error, self.known_word, self.hint = what, error, known_word, hint
        self._load = load
        self._entries: dict[str, T] = {}

    def add(self, name: str, entry: T) -> T:
        """Register `entry` under `name`; the same entry again is a no-op, another one an error."""
        old = self._entries.get(name)
        if old is not None and old is not entry:
            raise self.error(f"{self.what} name {name!r} is already registered by "
                             f"{getattr(old, '__name__', repr(old))}")
        self._entries[name] = entry
        return entry

    def get(self, name: str) -> T:
        """The entry called `name`; an unknown name raises the registry's error listing the known ones."""
        self._ensure_loaded()
        try:
            return self._entries[name]
        except KeyError:
            raise unknown_name(self.what, name, self._entries, error=self.error, known_word=self.known_word,
                               hint=self.hint) from None

    def names(self) -> list[str]:
        """Every name, in the order added."""
        self._ensure_loaded()
        return list(self._entries)

    def __contains__(self, name: object) -> bool:
        self._ensure_loaded()
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())

    def __getitem__(self, name: str) -> T:
        return self.get(name)

    def _ensure_loaded(self) -> None:
        load, self._load = self._load, None   # cleared first: loading adds entries (and may look them up)
        if load is not None:
            try:
                load(self)
            except BaseException:
                self._load = load                 # a failed load is tried again, not taken as complete
                raise
