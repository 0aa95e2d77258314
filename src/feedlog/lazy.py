"""Registries of things imported only when first asked for: a name maps to `"module:attribute"`."""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from feedlog.errors import FeedlogError
from feedlog.registry import unknown_name


def load_entry(registry: Mapping[str, str], name: str, *, what: str, error: type[FeedlogError] = FeedlogError) -> Any:
    """The attribute `registry[name]` names, imported now; an unknown name raises `error` listing the known."""
    try:
        target = registry[name]
    except KeyError:
        raise unknown_name(what, name, sorted(registry), error=error) from None
    module, attribute = target.split(":")
    return getattr(importlib.import_module(module), attribute)
