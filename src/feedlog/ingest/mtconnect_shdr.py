"""MTConnect SHDR text (the adapter-to-agent protocol, as adapters and test beds log it) -> observations.

A line is `TIMESTAMP|key|value|key|value...` (SHDR 2.0): an ISO 8601 UTC timestamp (optionally with
`@duration`), then key/value pairs; a key may carry a device prefix (`mill:Xact`). Lines whose fields
after the timestamp are not pairs carry one data item of another representation: a condition
(`key|level|native_code|severity|qualifier|text`), a message (`key|native_code|text`) or a time series
(`key|count|rate|v1 v2 ...`); feedlog keeps samples and events only, so those lines are counted
(`other_records`) and skipped, unless they carry a key the mapping asked for: that is a bad line.
`* command: value` lines (adapter commands), blank lines and multiline asset bodies
(`--multiline--ID` ... `--multiline--ID`) are no data. `* relativeTime: yes` makes timestamps
milliseconds from an arbitrary origin. Splitting is vectorised over the whole file (pyarrow);
values stay text here (`mtconnect.pivot` converts them).

A line that cannot be read (no timestamp, a timestamp that is not one, a value without its key)
goes to `BadRows` with its line number: strict import stops there, lenient import skips and counts it.
Lines may end in LF, CR LF or a lone CR; a UTF-8 BOM is skipped, UTF-16 is refused with a message.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from feedlog.errors import IngestError
from feedlog.ingest.csv_reader import BadRows
from feedlog.ingest.mtconnect_obs import Observations, parse_times

_MULTILINE = re.compile(r"--multiline--(\S+)")
_ESCAPED = re.compile(r"(?<!\\)\|")
CONDITION_LEVELS = ("NORMAL", "WARNING", "FAULT")


def read_text_lines(path: Path) -> list[str]:
    """The file's lines (line ends LF, CR LF or lone CR), BOM removed; UTF-16 and non-UTF-8 refused."""
    raw = path.read_bytes()
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise IngestError("the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8",
                          file=str(path), line=1)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + raw[:exc.start].count(b"\r") - raw[:exc.start].count(b"\r\n") + 1
        raise IngestError(f"not UTF-8 text (byte {exc.start}: {raw[exc.start:exc.start + 1]!r})", file=str(path),
                          line=line) from None
    if "\x00" in text:
        raise IngestError("binary data (a NUL byte) in a text file", file=str(path),
                          line=text[:text.index("\x00")].count("\n") + 1)
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def read_shdr(path: Path, *, wanted: set[str] | None = None, timezone: str = "UTC",
              device: str | None = None) -> Observations:
    """Every sample/event observation of an SHDR log, in file order, with line numbers. `wanted`: keys
    the caller maps (a condition, message or time-series line carrying one is a bad line); `device`:
    keep only keys with that device prefix (and keys without any)."""
    lines = read_text_lines(path)
    bad = BadRows()
    skip = np.zeros(len(lines), dtype=bool)
    relative = False
    commands: dict[str, str] = {}
    joined = "\n".join(lines)
    if "--multiline--" in joined:  # asset bodies between --multiline--ID markers are no data
        open_id = None
        for i, text in enumerate(lines):
            m = _MULTILINE.search(text)
            if open_id is not None:
                skip[i] = True
                if text.strip() == f"--multiline--{open_id}":
                    open_id = None
            elif m and "@ASSET@" in text:
                skip[i], open_id = True, m.group(1)
    stripped = pc.utf8_trim_whitespace(pa.array(lines, pa.string()))
    empty = pc.equal(pc.utf8_length(stripped), 0).to_numpy(zero_copy_only=False)
    command = pc.starts_with(stripped, "*").to_numpy(zero_copy_only=False)
    for i in np.flatnonzero(command & ~skip):
        key, _, value = lines[i].lstrip("* ").partition(":")
        commands[key.strip().lower()] = value.strip()
    relative = commands.get("relativetime", "").lower() in ("yes", "true")
    data = ~(empty | command | skip)
    rows = np.flatnonzero(data)
    if not len(rows):
        raise IngestError("no SHDR data lines (TIMESTAMP|key|value...)", file=str(path), line=1)
    texts = stripped.take(pa.array(rows))
    if not pc.any(pc.match_substring(texts, "|")).as_py():
        raise IngestError("not an SHDR log: no line holds TIMESTAMP|key|value fields (a CSV or text export saved "
                          "as .txt? read it as csv:FILE with --preset or --map)", file=str(path), line=int(rows[0]) + 1)
    if pc.any(pc.match_substring(texts, "\\|")).as_py():
        parts = pa.array([_ESCAPED.split(t) for t in texts.to_pylist()], pa.list_(pa.string()))
    else:
        parts = pc.split_pattern(texts, "|")
    n = pc.list_value_length(parts).to_numpy(zero_copy_only=False).astype(np.int64)
    flat = parts.flatten()
    offsets = parts.offsets.to_numpy()[:-1].astype(np.int64)
    stamp = flat.take(pa.array(offsets))
    t_ns, t_ok = _times(stamp, relative=relative, timezone=timezone)
    line_no = rows + 1
    no_pair = n < 3
    bad.add(line_no[~t_ok], "not an SHDR timestamp (ISO 8601, e.g. 2018-05-01T12:00:00.123Z)")
    bad.add(line_no[t_ok & no_pair], "no key|value after the timestamp")
    first_key = flat.take(pa.array(np.minimum(offsets + 1, max(len(flat) - 1, 0)))).to_numpy(zero_copy_only=False) \
        if len(flat) else np.zeros(0, object)
    asset = np.array([str(k).startswith("@") for k in first_key], dtype=bool) & ~no_pair
    # a condition has six fields (key|level|native_code|severity|qualifier|text), an even count that
    # would read as three pairs: its level (NORMAL, WARNING, FAULT; UNAVAILABLE with empty fields after) tells
    first_value = flat.take(pa.array(np.minimum(offsets + 2, max(len(flat) - 1, 0)))).to_numpy(zero_copy_only=False) \
        if len(flat) else np.zeros(0, object)
    third_field = flat.take(pa.array(np.minimum(offsets + 3, max(len(flat) - 1, 0)))).to_numpy(zero_copy_only=False) \
        if len(flat) else np.zeros(0, object)
    level = np.array([str(v).strip().upper() for v in first_value], dtype=object)
    condition = (n == 7) & (np.isin(level, CONDITION_LEVELS) |
                            ((level == "UNAVAILABLE") & np.array([not str(f).strip() for f in third_field], dtype=bool)))
    pairs = t_ok & ~no_pair & ((n - 1) % 2 == 0) & ~asset & ~condition
    other = t_ok & ~no_pair & ~pairs
    other_records = int(other.sum())
    if other.any():  # condition, message, time series: one data item, many fields
        keys = flat.take(pa.array(offsets[other] + 1)).to_numpy(zero_copy_only=False)
        wanted_hit = np.array([_bare(k) in (wanted or set()) for k in keys], dtype=bool)
        if wanted_hit.any():
            bad.add(line_no[other][wanted_hit], "a mapped key in a line that is not key|value pairs "
                                                "(a condition, message or time series)")
            other_records -= int(wanted_hit.sum())
    # key/value pairs of every pair line, vectorised: fields 1, 3, 5 ... are keys, 2, 4, 6 ... values
    sel = np.flatnonzero(pairs)
    npairs = (n[sel] - 1) // 2
    owner = np.repeat(sel, npairs)
    k = np.arange(int(npairs.sum())) - np.repeat(np.cumsum(npairs) - npairs, npairs)
    key_at = offsets[owner] + 1 + 2 * k
    key = flat.take(pa.array(key_at)).to_numpy(zero_copy_only=False)
    value = flat.take(pa.array(key_at + 1)).to_numpy(zero_copy_only=False)
    empty_key = np.array([not s.strip() for s in key], dtype=bool) if len(key) else np.zeros(0, bool)
    if empty_key.any():
        bad.add(line_no[owner[empty_key]], "an empty key")
    okk = ~empty_key
    prefix = np.array([s.strip().partition(":")[0] if ":" in s else "" for s in key], dtype=object)
    if device:
        okk &= (prefix == device) | (prefix == "")
    obs = Observations(t_ns=t_ns[owner][okk], key=np.array([_bare(s) for s in key[okk]], dtype=object),
                       value=value[okk].astype(object), where=line_no[owner][okk], bad=bad,
                       metadata={"format": "MTConnect SHDR", "other_records": str(other_records),
                                 **({"shdr_" + k: v for k, v in commands.items() if k in
                                     ("device", "shdrversion", "mtconnectversion", "manufacturer",
                                      "serialnumber", "relativetime")})},
                       place="line")
    devices = set(prefix[okk].tolist()) - {""}
    if devices:
        obs.metadata["devices"] = ",".join(sorted(devices))
    return obs


def _bare(key: str) -> str:
    """`device:key` -> `key` (feedlog reads one device at a time)."""
    key = key.strip()
    return key.partition(":")[2] if ":" in key else key


def _times(stamp: pa.Array, *, relative: bool, timezone: str) -> tuple[np.ndarray, np.ndarray]:
    """SHDR timestamps -> (int64 ns, ok). `@duration` suffixes are dropped."""
    text = pc.utf8_trim_whitespace(pc.replace_substring_regex(stamp, "@.*$", ""))
    values = text.to_numpy(zero_copy_only=False)
    if relative:
        ms = pd.to_numeric(pd.Series(values, dtype=object), errors="coerce").to_numpy(np.float64)
        ok = np.isfinite(ms) & (np.abs(ms) < 4.6e15)
        return np.where(ok, np.rint(np.nan_to_num(ms) * 1e6), 0).astype(np.int64), ok
    return parse_times(values, timezone=timezone)
