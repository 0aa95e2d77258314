"""MTConnect Streams XML (an agent's `/sample` or `/current` response, or many of them in one file) -> observations.

    <MTConnectStreams ...><Header .../><Streams>
      <DeviceStream name="Mazak" uuid="...">
        <ComponentStream component="Linear" name="X" componentId="x">
          <Samples><Position dataItemId="Xabs" name="Xabs" subType="ACTUAL" sequence="12"
                             timestamp="2018-05-01T12:00:00.123Z">12.5</Position></Samples>
        ...

Read with the standard library's expat parser (events, so a day of samples never becomes a tree), one
observation per element under `Samples` or `Events` (conditions are skipped). Each data item's type
(element name, `subType`, component and its name) is kept so that `mtconnect.auto_mapping` can find
the axes, the path feed and the line without a mapping. A file may hold several documents one after
the other (a logger that saved every response): they are read in turn and observations that two
responses repeat (same data item and sequence) are kept once. Documents with a DOCTYPE or entity
declarations are refused (MTConnect uses neither; refusing them keeps entity expansion out), an
`MTConnectError` document is an error, and malformed XML names the file and line.
"""

from __future__ import annotations

import re
from pathlib import Path
from xml.parsers import expat

import numpy as np

from feedlog.errors import IngestError
from feedlog.ingest.csv_reader import BadRows
from feedlog.ingest.mtconnect_obs import DataItemType, Observations, parse_times

CATEGORIES = ("Samples", "Events", "Condition")
_DECL = re.compile(rb"<\?xml\b")
_ROOT = re.compile(rb"<(?:\w+:)?MTConnect(?:Streams|Error)\b")


def _local(name: str) -> str:
    return name.rsplit(" ", 1)[-1].rsplit(":", 1)[-1]


class _Reader:
    """expat handlers collecting observations of one or more Streams documents."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.stack: list[str] = []
        self.component = ("", "")
        self.device = ""
        self.devices: list[str] = []
        self.obs: dict | None = None        # the observation element being read
        self.depth_obs = -1
        self.rows: list[tuple] = []          # (timestamp text, key, value, line, sequence)
        self.types: dict[str, DataItemType] = {}
        self.error: str | None = None
        self.header: dict[str, str] = {}
        self.line_offset = 0
        self.root = ""

    def fail(self, parser, message: str) -> None:
        raise IngestError(message, file=self.file, line=parser.CurrentLineNumber + self.line_offset)

    def start(self, parser, name: str, attrs: dict[str, str]) -> None:
        local = _local(name)
        depth = len(self.stack)
        if depth == 0:
            self.root = local
            if local == "MTConnectError":
                self.error = ""
            elif local != "MTConnectStreams":
                self.fail(parser, f"not an MTConnect Streams document (root element {local!r}); feedlog reads "
                                  "an agent's sample/current responses (MTConnectStreams)")
        if local == "Header" and depth == 1:
            self.header = {k: v for k, v in attrs.items() if k in ("creationTime", "instanceId", "version", "sender")}
        elif local == "Error" and self.error is not None:
            code = attrs.get("errorCode", "")
            self.error += f"{code}: " if code else ""
        elif local == "DeviceStream":
            self.device = attrs.get("name", attrs.get("uuid", ""))
            if self.device not in self.devices:
                self.devices.append(self.device)
        elif local == "ComponentStream":
            self.component = (attrs.get("component", ""), attrs.get("name", attrs.get("componentId", "")))
        elif self.stack and self.stack[-1] in CATEGORIES and self.obs is None and self.stack[-1] != "Condition":
            item = attrs.get("dataItemId") or attrs.get("name")
            if not item:
                self.fail(parser, f"<{local}> without a dataItemId")
            self.obs = {"key": item, "timestamp": attrs.get("timestamp", ""), "sequence": attrs.get("sequence", ""),
                        "line": parser.CurrentLineNumber + self.line_offset, "text": []}
            self.depth_obs = depth
            if item not in self.types:
                self.types[item] = DataItemType(element=local, category=self.stack[-1],
                                                sub_type=attrs.get("subType", ""), component=self.component[0],
                                                component_name=self.component[1], name=attrs.get("name", ""),
                                                device=self.device)
        self.stack.append(local)

    def end(self, parser, name: str) -> None:
        self.stack.pop()
        if self.obs is not None and len(self.stack) == self.depth_obs:
            o = self.obs
            self.rows.append((o["timestamp"], o["key"], "".join(o["text"]).strip(), o["line"], o["sequence"]))
            self.obs = None
        elif _local(name) == "ComponentStream":
            self.component = ("", "")

    def text(self, data: str) -> None:
        if self.obs is not None and len(self.stack) == self.depth_obs + 1:
            self.obs["text"].append(data)
        elif self.error is not None and self.stack and self.stack[-1] == "Error":
            self.error += data


def _parse_document(data: bytes, reader: _Reader) -> None:
    parser = expat.ParserCreate(namespace_separator=" ")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)

    def no_dtd(*_args) -> None:
        reader.fail(parser, "a DOCTYPE or entity declaration: MTConnect documents have none (refused)")

    parser.StartDoctypeDeclHandler = no_dtd
    parser.EntityDeclHandler = no_dtd
    parser.StartElementHandler = lambda name, attrs: reader.start(parser, name, attrs)
    parser.EndElementHandler = lambda name: reader.end(parser, name)
    parser.CharacterDataHandler = reader.text
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise IngestError(f"malformed XML: {expat.ErrorString(exc.code)} (column {exc.offset + 1})",
                          file=reader.file, line=(exc.lineno or 1) + reader.line_offset) from None
    if reader.error is not None:
        raise IngestError(f"an MTConnectError document: {reader.error.strip() or 'no message'}", file=reader.file,
                          line=reader.line_offset + 1)


def read_streams_xml(path: Path, *, timezone: str = "UTC") -> Observations:
    """Every sample and event of the Streams document(s) in `path`, ordered by time (then sequence)."""
    raw = path.read_bytes()
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise IngestError("the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save it as UTF-8",
                          file=str(path), line=1)
    raw = raw.removeprefix(b"\xef\xbb\xbf")
    # documents start at their XML declarations, or (files without any) at their root elements
    docs = [m.start() for m in _DECL.finditer(raw)] or [m.start() for m in _ROOT.finditer(raw)]
    if not docs:
        raise IngestError("no MTConnectStreams document in the file", file=str(path), line=1)
    if raw[:docs[0]].strip():
        raise IngestError("text before the first XML document", file=str(path), line=1)
    reader = _Reader(str(path))
    for i, start in enumerate(docs):
        end = docs[i + 1] if i + 1 < len(docs) else len(raw)
        reader.line_offset = raw.count(b"\n", 0, start) + raw.count(b"\r", 0, start) - raw.count(b"\r\n", 0, start)
        reader.stack, reader.obs = [], None
        _parse_document(raw[start:end].replace(b"\r\n", b"\n").replace(b"\r", b"\n"), reader)
    bad = BadRows()
    rows = reader.rows
    if not rows:
        raise IngestError("the Streams document(s) hold no samples or events", file=str(path), line=1)
    stamp = np.array([r[0] for r in rows], dtype=object)
    key = np.array([r[1] for r in rows], dtype=object)
    value = np.array([r[2] for r in rows], dtype=object)
    where = np.array([r[3] for r in rows], dtype=np.int64)
    seq = np.array([int(r[4]) if r[4].isdigit() and len(r[4]) < 19 else -1 for r in rows], dtype=np.int64)
    t_ns, ok = parse_times(stamp, timezone=timezone)
    bad.add(where[~ok], "observation without a usable timestamp attribute (ISO 8601)")
    # the same observation in two saved responses: once (data item and sequence)
    keep = ok.copy()
    if len(docs) > 1 and (seq >= 0).any():
        frame = np.rec.fromarrays([key.astype(str), seq])
        _, first = np.unique(frame, return_index=True)
        unique = np.zeros(len(rows), dtype=bool)
        unique[first] = True
        keep &= unique | (seq < 0)
    order = np.lexsort((seq[keep], t_ns[keep]))
    idx = np.flatnonzero(keep)[order]
    metadata = {"format": "MTConnect Streams XML", "documents": str(len(docs)),
                "devices": ",".join(d for d in reader.devices if d), **{f"mtconnect_{k}": v for k, v in
                                                                        reader.header.items()}}
    return Observations(t_ns=t_ns[idx], key=key[idx], value=value[idx], where=where[idx], bad=bad,
                        metadata=metadata, types=reader.types, place="line")
