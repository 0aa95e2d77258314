"""The parts of a LinuxCNC INI file the interpreter reads: [RS274NGC] SUBROUTINE_PATH (colon separated),
PARAMETER_FILE, CENTER_ARC_RADIUS_TOLERANCE_MM/_INCH, and [EMCIO] TOOL_TABLE; relative paths are
relative to the INI's folder."""

from __future__ import annotations

import configparser
from pathlib import Path

from feedlog.errors import ProgramError


def read_ini(ini: str | Path, cls, **overrides):
    ini = Path(ini)
    parser = configparser.ConfigParser(strict=False, interpolation=None, inline_comment_prefixes=("#", ";"))
    parser.optionxform = str.upper
    try:
        text = ini.read_text(encoding="utf-8", errors="replace")
        parser.read_string(text, source=str(ini))
    except OSError as exc:
        raise ProgramError(f"cannot read INI file: {exc.strerror or exc}", file=str(ini)) from None
    except configparser.Error as exc:
        raise ProgramError(f"malformed INI file: {exc}", file=str(ini)) from None

    def get(section: str, key: str) -> str | None:
        return parser.get(section, key, fallback=None) if parser.has_section(section) else None

    def path(value: str | None) -> Path | None:
        if not value:
            return None
        p = Path(value.strip()).expanduser()
        return p if p.is_absolute() else ini.parent / p

    def number(key: str) -> float | None:
        value = get("RS274NGC", key)
        if value is None:
            return None
        try:
            return float(value)
        except ValueError:
            raise ProgramError(f"[RS274NGC] {key} = {value!r} is not a number", file=str(ini)) from None

    subs = get("RS274NGC", "SUBROUTINE_PATH")
    values = dict(search_path=tuple(path(s) for s in subs.split(":") if s.strip()) if subs else (),
                  tool_table=path(get("EMCIO", "TOOL_TABLE")),
                  parameter_file=path(get("RS274NGC", "PARAMETER_FILE")),
                  arc_tolerance_mm=number("CENTER_ARC_RADIUS_TOLERANCE_MM"),
                  arc_tolerance_inch=number("CENTER_ARC_RADIUS_TOLERANCE_INCH"))
    if values["parameter_file"] is not None and not values["parameter_file"].exists():
        values["parameter_file"] = None     # LinuxCNC creates it on first use
    values.update({k: v for k, v in overrides.items() if v is not None})
    return cls(**values)
