"""Named entries of one kind (commands, readers, sources, mechanisms, learners, families): add, look up, list.

`Registry("model", error=ModelError, load=...)` keeps entries in the order they were added. An entry
is an object, or a lazy target `"module:attribute"` (or `"module"`) imported when it is first asked
for (`Registry.lazy(what, {name: target})`, one line per entry), so a command does not pay for torch.
`load` fills a registry on first use (built-ins register themselves when their modules are imported,
or are found on disk). An unknown name raises the registry's error listing the names it knows; a name
added twice with a different entry is refused; a target whose own module or attribute does not exist
raises one error naming the registry, the entry and the target (`unavailable=` words it for a registry
that says it otherwise). An import error inside an existing module (a missing dependency) propagates.
`import_target` is that import for a target held elsewhere (a mechanism's windowed `stream` class).
"""

from __future__ import annotations

import importlib
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from feedlog.errors import FeedlogError

T = TypeVar("T")


def unknown_name(what: str, name: str, known: Iterable[str], *, error: type[FeedlogError] = FeedlogError,
                 known_word: str = "known", hint: str = "") -> FeedlogError:
    """The error for a name no registry entry has: `unknown model 'x'; known: a, b`."""
    return error(f"unknown {what} {name!r}; {known_word}: {', '.join(known)}{hint}")


class TargetMissing(FeedlogError):
    """A lazy target names a module or an attribute that does not exist."""

    def __init__(self, target: str, module: str, attribute: str, cause: ModuleNotFoundError | None) -> None:
        self.target, self.module, self.attribute, self.cause = target, module, attribute, cause
        super().__init__(f"{module} cannot be imported: {cause}" if cause is not None
                         else f"{module} has no {attribute}")


def import_target(target: str) -> Any:
    """The module `"module"` or the attribute `"module:attribute"` names, imported now.

    Raises `TargetMissing` when that module (or a package above it) or that attribute does not exist."""
    module_name, _, attribute = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and (module_name == exc.name or module_name.startswith(exc.name + ".")):
            raise TargetMissing(target, module_name, attribute, exc) from None
        raise
    if not attribute:
        return module
    try:
        return getattr(module, attribute)
    except AttributeError:
        raise TargetMissing(target, module_name, attribute, None) from None


@dataclass(frozen=True)
class _Lazy:
    target: str


Unavailable = Callable[[str, TargetMissing], FeedlogError]


class Registry(Generic[T]):
    """Entries (objects or lazy `"module:attribute"` targets) by name, in the order added."""

    def __init__(self, what: str, *, error: type[FeedlogError] = FeedlogError,
                 load: Callable[[Registry[T]], None] | None = None, known_word: str = "known", hint: str = "",
                 sort_known: bool = False, unavailable: Unavailable | None = None) -> None:
        self.what, self.error, self.known_word, self.hint = what, error, known_word, hint
        self.sort_known, self.unavailable = sort_known, unavailable
        self._load = load
        self._loaded = load is None
        self._lock = threading.RLock()   # one thread fills it; the others wait (threads that record at once)
        self._entries: dict[str, T | _Lazy] = {}
        self._docs: dict[str, str] = {}

    @classmethod
    def lazy(cls, what: str, targets: Mapping[str, str | tuple[str, str]], **options: Any) -> Registry[Any]:
        """A registry of lazy targets: name -> `"module:attribute"`, or (target, one-line description)."""
        reg: Registry[Any] = cls(what, **options)
        for name, value in targets.items():
            target, doc = (value, "") if isinstance(value, str) else value
            reg.add_lazy(name, target, doc=doc)
        return reg

    def add(self, name: str, entry: T) -> T:
        """Register `entry` under `name`; the same entry again is a no-op, another one an error."""
        self._put(name, entry)
        return entry

    def add_lazy(self, name: str, target: str, *, doc: str = "") -> None:
        """Register `"module:attribute"` (or `"module"`) under `name`, imported when first asked for."""
        self._put(name, _Lazy(target))
        if doc:
            self._docs[name] = doc

    def _put(self, name: str, entry: T | _Lazy) -> None:
        old = self._entries.get(name)
        if old is not None and old is not entry and not (isinstance(old, _Lazy) and old == entry):
            taken_by = old.target if isinstance(old, _Lazy) else getattr(old, "__name__", repr(old))
            raise self.error(f"{self.what} name {name!r} is already registered by {taken_by}")
        self._entries[name] = entry

    def get(self, name: str) -> T:
        """The entry called `name` (a lazy one imported now); an unknown name raises the registry's error
        listing the known ones, a target that does not exist one naming registry, entry and target."""
        entry = self._entry(name)
        if not isinstance(entry, _Lazy):
            return entry
        try:
            return import_target(entry.target)
        except TargetMissing as missing:
            if self.unavailable is not None:
                raise self.unavailable(name, missing) from None
            raise self.error(f"{self.what} {name!r}: {entry.target} is not available ({missing})") from None

    def get_optional(self, name: str) -> T | None:
        """`get`, or None when the entry's own module or attribute does not exist in this installation."""
        try:
            entry = self._entry(name)
            return import_target(entry.target) if isinstance(entry, _Lazy) else entry
        except TargetMissing:
            return None

    def target(self, name: str) -> str | None:
        """The `"module:attribute"` a lazy entry names (None for an object entry)."""
        entry = self._entry(name)
        return entry.target if isinstance(entry, _Lazy) else None

    def doc(self, name: str) -> str:
        """The one-line description given with the entry ("" when none)."""
        self._entry(name)
        return self._docs.get(name, "")

    def copy(self, replace: Mapping[str, str] | None = None) -> Registry[T]:
        """The same registry (settings and entries), with the lazy targets in `replace` swapped in."""
        self._ensure_loaded()
        other: Registry[T] = Registry(self.what, error=self.error, known_word=self.known_word, hint=self.hint,
                                      sort_known=self.sort_known, unavailable=self.unavailable)
        other._entries, other._docs = dict(self._entries), dict(self._docs)
        for name, target in (replace or {}).items():
            other._entries[name] = _Lazy(target)
        return other

    def _entry(self, name: str) -> T | _Lazy:
        self._ensure_loaded()
        try:
            return self._entries[name]
        except KeyError:
            known = sorted(self._entries) if self.sort_known else self._entries
            raise unknown_name(self.what, name, known, error=self.error, known_word=self.known_word,
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
        if self._loaded:
            return
        with self._lock:  # another thread asking meanwhile waits here instead of seeing a half-filled registry
            load, self._load = self._load, None   # cleared first: loading adds entries (and may look them up)
            if load is None:                      # the loading thread itself, looking an entry up
                return
            try:
                load(self)
            except BaseException:
                self._load = load                 # a failed load is tried again, not taken as complete
                raise
            self._loaded = True
