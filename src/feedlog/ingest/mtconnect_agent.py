"""The MTConnect agent protocol as a client sees it: probe and streams documents, HTTP, multipart.

- `parse_probe(data)`: an `MTConnectDevices` document (`/probe`) -> the devices and their data items
  (id, category, type, subType, units, the component they belong to: its element such as `Linear`
  or `Rotary`, and its name such as `X`).
- `parse_streams(data)`: an `MTConnectStreams` document (`/current`, `/sample`) -> its header
  (instanceId, firstSequence, nextSequence, lastSequence, creationTime) and observations
  (dataItemId, sequence, timestamp text, value text); an `MTConnectError` document -> its error codes.
- `AgentClient`: GET a document, or stream the parts of a `multipart/x-mixed-replace` response
  (`/sample?interval=MS`), over the standard library's `http.client`.

Every document is parsed with expat in one go from bytes the caller already holds (parts are at most
`MAX_DOCUMENT_BYTES`); DOCTYPE and entity declarations are refused (MTConnect uses neither, and
refusing them keeps entity expansion out). Anything malformed is an `IngestError` naming the URL.
A multipart part that claims more than `MAX_DOCUMENT_BYTES` is refused before anything is read.
"""

from __future__ import annotations

import http.client
import socket
import urllib.parse
from dataclasses import dataclass, field
from collections.abc import Iterator
from xml.parsers import expat

from feedlog.errors import IngestError

MAX_DOCUMENT_BYTES = 64 << 20   # one probe or streams document (a large agent's probe is a few MB)
MAX_HEADER_BYTES = 16 << 10     # the header block of one multipart part
READ_BYTES = 1 << 16


def _local(name: str) -> str:
    return name.rsplit(" ", 1)[-1].rsplit(":", 1)[-1]


@dataclass(frozen=True)
class DataItem:
    """A data item as the probe describes it."""

    id: str
    category: str           # SAMPLE, EVENT, CONDITION
    type: str               # POSITION, PATH_FEEDRATE, LINE_NUMBER, EXECUTION, ...
    sub_type: str = ""      # ACTUAL, COMMANDED, PROGRAMMED, ABSOLUTE, ...
    units: str = ""         # MILLIMETER, MILLIMETER/SECOND, DEGREE, ...
    component: str = ""     # the element of the component it belongs to: Linear, Rotary, Path, Controller
    component_name: str = ""  # its name (or id): X, Y, C, path1
    name: str = ""
    device: str = ""
    native_units: str = ""  # the adapter's unit the agent converts from (`nativeUnits`), when given
    coordinate_system: str = ""  # MACHINE or WORK, when given


@dataclass
class Device:
    name: str
    uuid: str = ""
    items: list[DataItem] = field(default_factory=list)


@dataclass
class Observation:
    item: str
    sequence: int
    timestamp: str
    value: str


@dataclass
class StreamsDocument:
    """One `MTConnectStreams` response, or an `MTConnectError` (`errors` not empty)."""

    header: dict[str, str] = field(default_factory=dict)
    observations: list[Observation] = field(default_factory=list)
    errors: list[tuple[str, str]] = field(default_factory=list)   # (errorCode, text)

    def header_int(self, key: str) -> int | None:
        text = self.header.get(key, "")
        return int(text) if text.isascii() and text.isdigit() and len(text) < 19 else None


def _parser(where: str, fail) -> expat.XMLParserType:
    parser = expat.ParserCreate(namespace_separator=" ")
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)

    def no_dtd(*_args) -> None:
        fail("a DOCTYPE or entity declaration: MTConnect documents have none (refused)")

    parser.StartDoctypeDeclHandler = no_dtd
    parser.EntityDeclHandler = no_dtd
    return parser


def _parse(data: bytes, where: str, handlers) -> None:
    """Run expat over `data` with `handlers(parser, fail)` -> (start, end, text)."""
    if len(data) > MAX_DOCUMENT_BYTES:
        raise IngestError(f"a document of {len(data)} bytes (at most {MAX_DOCUMENT_BYTES} are read)", file=where)
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise IngestError("the document is UTF-16 (MTConnect agents send UTF-8)", file=where)
    parser = None

    def fail(message: str) -> None:
        raise IngestError(message, file=where, line=parser.CurrentLineNumber if parser else None)

    parser = _parser(where, fail)
    start, end, text = handlers(parser, fail)
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise IngestError(f"malformed XML: {expat.ErrorString(exc.code)} (column {exc.offset + 1})", file=where,
                          line=exc.lineno or 1) from None
    except RecursionError:
        raise IngestError("elements nested too deeply", file=where) from None


def parse_probe(data: bytes, where: str = "probe") -> list[Device]:
    """The devices of an `MTConnectDevices` document and their data items, in document order."""
    devices: list[Device] = []
    stack: list[tuple[str, dict[str, str]]] = []
    root: list[str] = []
    errors: list[str] = []

    def handlers(parser, fail):
        def start(name: str, attrs: dict[str, str]) -> None:
            local = _local(name)
            if not stack:
                root.append(local)
                if local not in ("MTConnectDevices", "MTConnectError"):
                    fail(f"not an MTConnect probe response (root element {local!r}, expected MTConnectDevices)")
            if local == "Device" and len(stack) >= 1 and stack[-1][0] == "Devices":
                devices.append(Device(name=attrs.get("name") or attrs.get("uuid") or attrs.get("id", ""),
                                      uuid=attrs.get("uuid", "")))
            elif local == "DataItem" and stack and stack[-1][0] == "DataItems" and devices:
                owner = stack[-2] if len(stack) >= 2 else ("", {})
                item_id = attrs.get("id", "")
                if not item_id:
                    fail("<DataItem> without an id")
                devices[-1].items.append(DataItem(
                    id=item_id, category=attrs.get("category", "").upper(), type=attrs.get("type", "").upper(),
                    sub_type=attrs.get("subType", "").upper(), units=attrs.get("units", "").upper(),
                    component=owner[0], component_name=owner[1].get("name") or owner[1].get("id", ""),
                    name=attrs.get("name", ""), device=devices[-1].name,
                    native_units=attrs.get("nativeUnits", "").upper(),
                    coordinate_system=attrs.get("coordinateSystem", "").upper()))
            elif local == "Error" and root and root[0] == "MTConnectError":
                errors.append(attrs.get("errorCode", ""))
            stack.append((local, attrs))

        def end(name: str) -> None:
            stack.pop()

        return start, end, lambda text: None

    _parse(data, where, handlers)
    if root and root[0] == "MTConnectError":
        raise IngestError(f"the agent answered the probe with an error: {', '.join(e for e in errors if e) or '?'}",
                          file=where)
    return devices


def parse_streams(data: bytes, where: str = "sample") -> StreamsDocument:
    """An `MTConnectStreams` document: header and the observations under Samples and Events
    (conditions are left out); or an `MTConnectError` document's error codes."""
    doc = StreamsDocument()
    stack: list[str] = []
    current: list = []          # [Observation, text parts, depth] of the element being read
    error: list = []            # [code, text parts] of the Error being read

    def handlers(parser, fail):
        def start(name: str, attrs: dict[str, str]) -> None:
            local = _local(name)
            depth = len(stack)
            if depth == 0 and local not in ("MTConnectStreams", "MTConnectError"):
                fail(f"not an MTConnect streams response (root element {local!r})")
            if local == "Header" and depth == 1:
                doc.header = dict(attrs)
            elif local == "Error" and stack and stack[0] == "MTConnectError":
                error[:] = [attrs.get("errorCode", ""), []]
            elif stack and stack[-1] in ("Samples", "Events") and not current:
                item = attrs.get("dataItemId", "")
                seq = attrs.get("sequence", "")
                if not item or not (seq.isascii() and seq.isdigit() and len(seq) < 19):
                    fail(f"<{local}> without a dataItemId and a sequence number")
                current[:] = [Observation(item, int(seq), attrs.get("timestamp", ""), ""), [], depth]
            stack.append(local)

        def end(name: str) -> None:
            stack.pop()
            if current and len(stack) == current[2]:
                obs = current[0]
                obs.value = "".join(current[1]).strip()
                doc.observations.append(obs)
                current.clear()
            elif error and _local(name) == "Error":
                doc.errors.append((error[0], "".join(error[1]).strip()))
                error.clear()

        def text(data: str) -> None:
            if current and len(stack) == current[2] + 1:
                current[1].append(data)
            elif error:
                error[1].append(data)

        return start, end, text

    _parse(data, where, handlers)
    if stack and stack[0] == "MTConnectError" and not doc.errors:
        doc.errors.append(("", "an MTConnectError document without an Error"))
    return doc


class AgentUnreachable(Exception):
    """The agent cannot be reached or the connection broke (the recorder reconnects)."""


@dataclass
class Response:
    status: int
    content_type: str
    body: bytes


class AgentClient:
    """HTTP access to one agent (`http://HOST:PORT[/prefix]`), one request at a time."""

    def __init__(self, url: str, *, timeout_s: float = 10.0) -> None:
        parts = urllib.parse.urlsplit(url.strip())
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise IngestError(f"bad agent URL {url!r}: give http://HOST:PORT (e.g. http://192.168.1.20:5000)")
        try:
            self.port = parts.port or (443 if parts.scheme == "https" else 80)
        except ValueError:
            raise IngestError(f"bad agent URL {url!r}: the port is not a number from 1 to 65535") from None
        if parts.query or parts.fragment:
            raise IngestError(f"bad agent URL {url!r}: give the agent's address without a query")
        self.url = urllib.parse.urlunsplit((parts.scheme, parts.netloc, parts.path.rstrip("/"), "", ""))
        self.host = parts.hostname
        self.prefix = parts.path.rstrip("/")
        self.https = parts.scheme == "https"
        self.timeout_s = timeout_s
        self._conn: http.client.HTTPConnection | None = None

    def _connect(self) -> http.client.HTTPConnection:
        cls = http.client.HTTPSConnection if self.https else http.client.HTTPConnection
        return cls(self.host, self.port, timeout=self.timeout_s)

    def _open(self, path: str) -> http.client.HTTPResponse:
        self.close()
        conn = self._connect()
        self._conn = conn
        try:
            conn.request("GET", self.prefix + path, headers={"Accept": "application/xml"})
            return conn.getresponse()
        except (OSError, http.client.HTTPException) as exc:
            self.close()
            raise AgentUnreachable(_reason(exc)) from None

    def get(self, path: str) -> Response:
        """One whole response (its body at most MAX_DOCUMENT_BYTES)."""
        resp = self._open(path)
        try:
            length = resp.getheader("Content-Length")
            if length and length.isascii() and length.isdigit() and int(length) > MAX_DOCUMENT_BYTES:
                raise IngestError(f"the agent announces a {length}-byte document (at most {MAX_DOCUMENT_BYTES})",
                                  file=self.url + path)
            body = resp.read(MAX_DOCUMENT_BYTES + 1)
            if len(body) > MAX_DOCUMENT_BYTES:
                raise IngestError(f"a document of more than {MAX_DOCUMENT_BYTES} bytes", file=self.url + path)
            return Response(resp.status, resp.getheader("Content-Type", ""), body)
        except (OSError, http.client.HTTPException) as exc:
            raise AgentUnreachable(_reason(exc)) from None
        finally:
            self.close()

    def stream(self, path: str) -> Iterator[Response]:
        """The parts of a multipart response as they arrive; a response that is not multipart is one
        part. Ends when the agent ends the response; AgentUnreachable when the connection breaks."""
        resp = self._open(path)
        try:
            ctype = resp.getheader("Content-Type", "")
            boundary = multipart_boundary(ctype)
            if boundary is None:
                body = resp.read(MAX_DOCUMENT_BYTES + 1)
                if len(body) > MAX_DOCUMENT_BYTES:
                    raise IngestError(f"a document of more than {MAX_DOCUMENT_BYTES} bytes", file=self.url + path)
                yield Response(resp.status, ctype, body)
                return
            for part_type, body in MultipartReader(resp.read1, boundary, where=self.url + path):
                yield Response(resp.status, part_type, body)
        except (OSError, http.client.HTTPException) as exc:
            raise AgentUnreachable(_reason(exc)) from None
        finally:
            self.close()

    def close(self) -> None:
        """Close the connection (from another thread too: a blocked read then ends)."""
        conn, self._conn = self._conn, None
        if conn is not None:
            sock = getattr(conn, "sock", None)
            if sock is not None:
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
            conn.close()


def _reason(exc: BaseException) -> str:
    if isinstance(exc, socket.timeout):
        return "no data within the timeout"
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc) or type(exc).__name__


def multipart_boundary(content_type: str) -> str | None:
    """The boundary of a `multipart/...; boundary=B` content type, None for anything else."""
    kind, _, params = content_type.partition(";")
    if not kind.strip().lower().startswith("multipart/"):
        return None
    for param in params.split(";"):
        key, _, value = param.strip().partition("=")
        if key.strip().lower() == "boundary" and value.strip().strip('"'):
            return value.strip().strip('"')
    raise IngestError(f"a multipart response without a boundary ({content_type[:80]!r})")


class MultipartReader:
    """Splits a multipart byte stream (`read(n)` returns what has arrived, b"" at its end) into
    (content type, body) parts. A part with Content-Length is read to that length; one without ends
    at the next boundary. Lengths beyond MAX_DOCUMENT_BYTES are refused before reading them."""

    def __init__(self, read, boundary: str, *, where: str = "multipart") -> None:
        self.read = read
        self.delimiter = b"--" + boundary.encode("latin-1")
        self.where = where
        self.buf = bytearray()
        self.eof = False

    def _fill(self) -> bool:
        if self.eof:
            return False
        data = self.read(READ_BYTES)
        if not data:
            self.eof = True
            return False
        self.buf += data
        return True

    def _until(self, token: bytes, limit: int) -> int:
        """Index of `token` in the buffer, reading more as needed; -1 at the end of the stream."""
        start = 0
        while True:
            at = self.buf.find(token, start)
            if at >= 0:
                return at
            if len(self.buf) > limit:
                raise IngestError(f"no {token[:40]!r} within {limit} bytes of the multipart stream", file=self.where)
            start = max(0, len(self.buf) - len(token) + 1)
            if not self._fill():
                return -1

    def __iter__(self) -> Iterator[tuple[str, bytes]]:
        while True:
            at = self._until(self.delimiter, MAX_DOCUMENT_BYTES)
            if at < 0:
                return
            del self.buf[:at + len(self.delimiter)]
            while len(self.buf) < 2 and self._fill():
                pass
            if self.buf[:2] == b"--":    # the closing delimiter
                return
            end = self._until(b"\r\n\r\n", MAX_HEADER_BYTES)
            if end < 0:
                return                    # the stream ended inside a part's headers: nothing complete
            headers = _part_headers(bytes(self.buf[:end]))
            del self.buf[:end + 4]
            length = headers.get("content-length")
            if length is not None:
                if not (length.isascii() and length.isdigit() and len(length) < 12):
                    raise IngestError(f"a multipart part with Content-length {length[:20]!r}", file=self.where)
                n = int(length)
                if n > MAX_DOCUMENT_BYTES:
                    raise IngestError(f"a multipart part of {n} bytes (at most {MAX_DOCUMENT_BYTES} are read)",
                                      file=self.where)
                while len(self.buf) < n and self._fill():
                    pass
                if len(self.buf) < n:
                    return                # cut off inside the part: the part never arrived whole
                body = bytes(self.buf[:n])
                del self.buf[:n]
            else:
                at = self._until(self.delimiter, MAX_DOCUMENT_BYTES)
                if at < 0:
                    return
                body = bytes(self.buf[:at]).removesuffix(b"\r\n")
                # the delimiter stays in the buffer for the next round
            yield headers.get("content-type", ""), body


def _part_headers(block: bytes) -> dict[str, str]:
    headers = {}
    for line in block.split(b"\r\n"):
        key, sep, value = line.partition(b":")
        if sep:
            headers[key.strip().decode("latin-1").lower()] = value.strip().decode("latin-1")
    return headers
