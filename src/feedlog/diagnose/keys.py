"""Profile parameters by dotted key, exactly as the profile TOML spells them.

`axes.x.acc_max`, `interpolator.servo_period_s`, `rapid_mm_min`, `sim.feed_override.override`,
`sim.following_lag.lag_s.x`, `kinematics.rotary_offset_mm.1` (one element of a list, counted from 0): a
key walks the profile's TOML tables. `value(profile, key)` reads the
value that is in force (for a `sim.<mechanism>` parameter the profile does not set: the mechanism's
default for that profile), `with_values(profile, {key: value})` returns a new, checked profile.
Setting a parameter of a mechanism the profile has switched off switches it on: that is how a
fitted finding extends the model. `unit(key)` names the unit from the key (rotary axes in degrees).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import numpy as np

from feedlog.errors import FeedlogError, ProfileError
from feedlog.profile import LINEAR_AXES, MachineProfile

SECTIONS = ("axes", "interpolator", "kinematics", "sim")
TOP_LEVEL = ("rapid_mm_min",)
# unit suffixes of feedlog's unit-named fields, longest first
_SUFFIX_UNITS = (("_mm_s2", "mm/s^2"), ("_mm_s", "mm/s"), ("_mm_min", "mm/min"), ("_deg_s", "deg/s"),
                 ("_mm", "mm"), ("_deg", "deg"), ("_s", "s"))
_AXIS_UNITS = {"vel_max": ("mm/s", "deg/s"), "acc_max": ("mm/s^2", "deg/s^2"), "jerk_max": ("mm/s^3", "deg/s^3"),
               "min_limit": ("mm", "deg"), "max_limit": ("mm", "deg")}


def split(key: str) -> list[str]:
    parts = key.split(".")
    if not all(parts) or (parts[0] not in SECTIONS and key not in TOP_LEVEL):
        raise ProfileError(f"{key!r} is not a profile key (sections: {', '.join(SECTIONS)}; or {', '.join(TOP_LEVEL)})")
    return parts


def unit(key: str) -> str:
    """The unit of a key's value ('' for ratios, counts and switches)."""
    parts = split(key)
    if parts[0] == "axes" and len(parts) == 3 and parts[2] in _AXIS_UNITS:
        return _AXIS_UNITS[parts[2]][0 if parts[1] in LINEAR_AXES else 1]
    name = parts[-2] if (parts[0] == "sim" and len(parts) == 4) or parts[-1].isdigit() else parts[-1]  # lag_s.x -> lag_s
    if name == "lookahead_blocks":
        return "blocks"
    for suffix, text in _SUFFIX_UNITS:
        if name.endswith(suffix):
            return text
    return ""


def _mechanism_params(profile: MachineProfile, mechanism: str) -> tuple[bool, dict[str, Any]]:
    """Whether a sim mechanism runs on `profile`, and its parameters in force."""
    from feedlog.sim.mechanism import resolve_mechanisms  # sim loads on first use

    for mech in resolve_mechanisms(profile):
        if mech.name == mechanism:
            return True, mech.params()
    from feedlog.sim.mechanism import mechanism_class

    cls = mechanism_class(mechanism)
    params = {k: v for k, v in profile.mechanism(mechanism).items() if k != "enabled"}
    return False, cls.from_params(profile, params).params()


def enabled(profile: MachineProfile, mechanism: str) -> bool:
    return _mechanism_params(profile, mechanism)[0]


def value(profile: MachineProfile, key: str) -> Any:
    """The value of `key` in force on `profile` (mechanism defaults for `sim.*` keys it does not set)."""
    parts = split(key)
    if parts[0] == "sim":
        if len(parts) < 3:
            raise ProfileError(f"{key!r}: a sim key is sim.<mechanism>.<param>[.<axis>]")
        try:
            _, params = _mechanism_params(profile, parts[1])
        except FeedlogError as exc:
            raise ProfileError(f"{key!r}: {exc}") from None
        node: Any = params
        for p in parts[2:]:
            if isinstance(node, Mapping):
                node = node.get(p, 0.0 if p in LINEAR_AXES + ("a", "b", "c") else None)
            else:
                node = None
            if node is None:
                raise ProfileError(f"{key!r}: mechanism {parts[1]!r} has no parameter {'.'.join(parts[2:])!r}")
        return node
    data = profile.to_dict()
    node = data
    for p in parts:
        if isinstance(node, list) and p.isdigit() and int(p) < len(node):  # one element of a list
            node = node[int(p)]
            continue
        if not isinstance(node, Mapping) or p not in node:
            default = _dataclass_default(profile, parts)
            if default is not None:
                return default
            raise ProfileError(f"{key!r} is not set in profile {profile.name!r}")
        node = node[p]
    if isinstance(node, Mapping):
        raise ProfileError(f"{key!r} names a table of profile {profile.name!r}, not a value")
    return node


def _dataclass_default(profile: MachineProfile, parts: list[str]) -> Any:
    """Values to_dict leaves out (infinite caps and limits) read from the dataclasses."""
    obj: Any = profile
    for p in parts:
        obj = obj.get(p) if isinstance(obj, Mapping) else getattr(obj, p, None)
        if obj is None:
            return None
    return obj


def with_values(profile: MachineProfile, values: Mapping[str, Any], *, name: str | None = None) -> MachineProfile:
    """A new profile with `values` set (checked like any profile). A `sim.<mechanism>` value switches
    its mechanism on (`enabled = true`) unless the values say otherwise."""
    data = copy.deepcopy(profile.to_dict())
    for key, v in values.items():
        parts = split(key)
        node = data
        if parts[0] != "sim" and parts[-1].isdigit():    # one element of a list (`kinematics.rotary_offset_mm.1`)
            listed = _walk(data, parts[:-1])
            if isinstance(listed, list) and int(parts[-1]) < len(listed):
                listed[int(parts[-1])] = _plain(v)
                continue
        for p in parts[:-1]:
            child = node.get(p)
            if not isinstance(child, dict):
                child = node[p] = {} if child is None else dict(child)
            node = child
        node[parts[-1]] = _plain(v)
        if parts[0] == "sim" and parts[-1] != "enabled" and len(parts) >= 3:
            table = data["sim"][parts[1]]
            if "enabled" not in table and not enabled(profile, parts[1]):
                table["enabled"] = True
            if len(parts) == 4:  # a per-axis entry of a dict parameter: keep the others in force
                current = value(profile, ".".join(parts[:3]))
                if isinstance(current, Mapping) and enabled(profile, parts[1]):
                    table[parts[2]] = {**{k: _plain(x) for k, x in current.items()}, **table[parts[2]]}
    if name is not None:
        data["name"] = name
    return MachineProfile.from_dict(data, source=f"{profile.name} + {', '.join(values)}")


def _walk(data: Mapping[str, Any], parts: list[str]) -> Any:
    node: Any = data
    for p in parts:
        if not isinstance(node, Mapping) or p not in node:
            return None
        node = node[p]
    return node


def _plain(v: Any) -> Any:
    """numpy scalars as Python numbers (TOML and the dataclass checks want plain values)."""
    return v.item() if isinstance(v, np.generic) else v


def diff(before: MachineProfile, after: MachineProfile) -> list[tuple[str, Any, Any]]:
    """(key, before, after) for every leaf that differs, in key order."""
    a, b = _leaves(before.to_dict()), _leaves(after.to_dict())
    out = []
    for key in sorted(set(a) | set(b)):
        if key in ("name", "description") or key.startswith("coverage."):
            continue
        if a.get(key) != b.get(key):
            out.append((key, a.get(key), b.get(key)))
    return out


def _leaves(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(_leaves(v, key + "."))
        else:
            out[key] = v
    return out
