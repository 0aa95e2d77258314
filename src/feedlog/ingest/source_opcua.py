"""`feedlog record --source opcua --url opc.tcp://HOST:4840 [--nodes MAP] -o REC.mcap`: an OPC UA server.

Which nodes (`resolve_nodes`):
- with `--nodes NAME|FILE.toml`, a node map: the node id of each signal (`[columns]`: x..c, x_cmd..c_cmd,
  feed, requested_feed, line, each with an optional unit; `[events]`: any name -> node id). Built in:
  `sinumerik`, `heidenhain` (`ingest/opcua_nodes/`, unverified on real hardware: see their notes);
- without it, the standard machine-tool layout where the server has it, found by browse name: the
  OPC UA for CNC Systems model (OPC 40502, used by the machine-tool companion specification OPC 40501 /
  umati): `CncInterface/CncAxisList/<X|Y|Z|A|B|C...>/PosIndirect` (or `PosDirect`) `/ActPos` and `/CmdPos`
  -> `axes` and `axes_commanded`, the first channel of `CncInterface/CncChannelList`: `ActFeedrate` ->
  `feed.feed_mm_min`, `CmdFeedrate` -> `feed.requested_feed_mm_min`, `ActProgramLine` -> `line`,
  `ActProgramName`, `ActProgramStatus`, `ToolId`, `ActProgramBlock` -> `events`; and OPC 40501's
  `Machines/<machine>/Monitoring/<channel>/ChannelState` -> `events` where present.
Units: the map's `unit`, else the variable's `EngineeringUnits` (UNECE code or display name), else
mm, deg and mm/min (said in the metadata).

All nodes are monitored in one subscription (sampling interval `--interval-ms`, a queue on the
server so that nothing sampled between two publishes is lost) and every value is stamped with its
server timestamp (the source timestamp when the server gives none). Values become rows as with
MTConnect (`live_rows`). A lost connection is a gap (`gaps` stream, lost = -1: the number of values is
unknown); asyncua reconnects and re-creates the subscription, and recording goes on.

Security (`security_settings`): `--security FILE.toml` and the environment (`FEEDLOG_OPCUA_USER`,
`FEEDLOG_OPCUA_PASSWORD`, `FEEDLOG_OPCUA_POLICY` e.g. `Basic256Sha256`, `FEEDLOG_OPCUA_MODE`
`SignAndEncrypt`|`Sign`, `FEEDLOG_OPCUA_CERT`, `FEEDLOG_OPCUA_KEY`, `FEEDLOG_OPCUA_KEY_PASSWORD`,
`FEEDLOG_OPCUA_SERVER_CERT`; the environment wins). None of it is written into the recording, only
the policy name and whether a user logged in. A refused login or certificate is one error line.
"""

from __future__ import annotations

import argparse
import asyncio
import datetime as dt
import logging
import os
import sys
import threading
import time
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from feedlog.errors import FeedlogError, IngestError, OutputError
from feedlog.ingest.live_rows import Column, Gap, Plan, Progress, RowSession, Stats, iso, record_from_args, stop_reason
from feedlog.ingest.mtconnect_agent import Observation
from feedlog.ingest.writer import RecordingWriter
from feedlog.errors import UnitError
from feedlog.units import angle_factor, length_factor, velocity_factor

STOPS_ON_EVENT = True  # cli_record: SIGINT/SIGTERM set args.stop_event

AXES = "xyzabc"
TARGETS = {**{a: ("axes", a) for a in AXES}, **{f"{a}_cmd": ("axes_commanded", a) for a in AXES},
           "feed": ("feed", "feed_mm_min"), "requested_feed": ("feed", "requested_feed_mm_min"), "line": ("line", "line")}
ENV = {"user": "FEEDLOG_OPCUA_USER", "password": "FEEDLOG_OPCUA_PASSWORD", "policy": "FEEDLOG_OPCUA_POLICY",
       "mode": "FEEDLOG_OPCUA_MODE", "certificate": "FEEDLOG_OPCUA_CERT", "private_key": "FEEDLOG_OPCUA_KEY",
       "private_key_password": "FEEDLOG_OPCUA_KEY_PASSWORD", "server_certificate": "FEEDLOG_OPCUA_SERVER_CERT"}
POLICIES = ("None", "Basic256Sha256", "Aes128Sha256RsaOaep", "Aes256Sha256RsaPss")
# UNECE Recommendation 20 codes (EUInformation.UnitId = the code's three characters as bytes)
UNECE = {"MMT": "mm", "INH": "in", "MTR": "m", "4H": "um", "DD": "deg", "C81": "rad", "H81": "mm/min",
         "C16": "mm/s", "2X": "m/min", "MTS": "m/s"}
LOGIN_REFUSED = {"BadUserAccessDenied", "BadIdentityTokenInvalid", "BadIdentityTokenRejected",
                 "BadUserSignatureInvalid"}
CERT_REFUSED = {"BadCertificateUntrusted", "BadSecurityChecksFailed", "BadCertificateInvalid",
                "BadCertificateUriInvalid", "BadCertificateTimeInvalid", "BadCertificateRevoked",
                "BadCertificateUseNotAllowed", "BadSecurityPolicyRejected", "BadSecurityModeRejected",
                "BadCertificateIssuerRevocationUnknown", "BadCertificateRevocationUnknown"}


def add_arguments(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--nodes", metavar="MAP", help="OPC UA: node map (sinumerik, heidenhain or a TOML file); "
                                                      "default: the standard CNC / machine-tool layout")
    group.add_argument("--security", metavar="FILE.toml",
                       help="OPC UA: policy, certificates, user and password (FEEDLOG_OPCUA_* override it)")


# -- node maps --------------------------------------------------------------------------------------------
@dataclass
class NodeMap:
    name: str
    columns: dict[str, tuple[str, str | None]] = field(default_factory=dict)   # target -> (node id, unit)
    events: dict[str, str] = field(default_factory=dict)                      # event name -> node id
    controller: str = ""
    verified: bool = False
    note: str = ""


def builtin_maps() -> list[str]:
    return sorted(p.name.removesuffix(".toml") for p in _maps_dir().iterdir() if p.name.endswith(".toml"))


def _maps_dir():
    return resources.files("feedlog.ingest") / "opcua_nodes"


def load_node_map(spec: str) -> NodeMap:
    """A node map by built-in name or TOML path; IngestError naming the file and the problem."""
    path = Path(spec)
    if spec in builtin_maps():
        text, where = (_maps_dir() / f"{spec}.toml").read_text("utf-8"), spec
    elif path.is_file():
        try:
            text, where = path.read_text("utf-8"), str(path)
        except (OSError, UnicodeDecodeError) as exc:
            raise IngestError(f"cannot read the node map: {exc}", file=str(path)) from None
    else:
        raise IngestError(f"no node map {spec!r}: give a TOML file or one of {', '.join(builtin_maps())}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise IngestError(f"not a TOML node map: {exc}", file=where) from None
    columns, events = data.get("columns", {}), data.get("events", {})
    if not isinstance(columns, dict) or not isinstance(events, dict):
        raise IngestError("[columns] and [events] must be tables", file=where)
    nmap = NodeMap(name=str(data.get("name", path.stem)), controller=str(data.get("controller", "")),
                   verified=bool(data.get("verified", False)), note=str(data.get("note", "")))
    for target, entry in columns.items():
        if target not in TARGETS:
            raise IngestError(f"[columns] {target!r} is not one of {', '.join(TARGETS)}", file=where)
        if isinstance(entry, str):
            entry = {"node": entry}
        if not isinstance(entry, dict) or not isinstance(entry.get("node"), str):
            raise IngestError(f"[columns] {target}: give node = \"ns=...;s=...\" (and unit = ...)", file=where)
        unit = entry.get("unit")
        if unit is not None:
            _unit_factor(target, str(unit), where)
        nmap.columns[target] = (entry["node"], None if unit is None else str(unit))
    for name, node in events.items():
        if not isinstance(node, str):
            raise IngestError(f"[events] {name}: give the node id as a string", file=where)
        nmap.events[str(name)] = node
    if not nmap.columns:
        raise IngestError("the node map has no [columns]", file=where)
    return nmap


def _unit_factor(target: str, unit: str, where: str = "") -> float:
    """Factor from `unit` to mm, deg or mm/min for `target`; 0 for the line number."""
    try:
        if target == "line":
            return 0.0
        if target in ("feed", "requested_feed"):
            return velocity_factor(unit)
        axis = target[0]
        return length_factor(unit) if axis in "xyz" else angle_factor(unit)
    except UnitError as exc:
        raise IngestError(f"{target}: {exc}", file=where or None) from None


def unit_from_eu(eu) -> str | None:
    """The unit an EUInformation names (UNECE code, else display name), None if neither is known."""
    unit_id = getattr(eu, "UnitId", None)
    if isinstance(unit_id, int) and 0 < unit_id < 1 << 32:   # an Int32 on the wire
        code = bytes(b for b in unit_id.to_bytes(4, "big") if b).decode("latin-1")
        if code in UNECE:
            return UNECE[code]
    name = getattr(getattr(eu, "DisplayName", None), "Text", None) or ""
    name = name.strip().replace("°", "deg").replace("inch", "in")
    return name or None


# -- security --------------------------------------------------------------------------------------------
def security_settings(path: str | None, environ=os.environ) -> dict[str, str]:
    """Security settings from the file, then the environment (which wins)."""
    settings: dict[str, str] = {}
    if path:
        try:
            data = tomllib.loads(Path(path).read_text("utf-8"))
        except (OSError, UnicodeDecodeError) as exc:
            raise IngestError(f"cannot read the security file: {getattr(exc, 'strerror', None) or exc}",
                              file=path) from None
        except tomllib.TOMLDecodeError as exc:
            raise IngestError(f"not a TOML security file: {exc}", file=path) from None
        unknown = sorted(set(data) - set(ENV))
        if unknown:
            raise IngestError(f"unknown keys {unknown}; known: {', '.join(ENV)}", file=path)
        settings.update({k: str(v) for k, v in data.items()})
    for key, var in ENV.items():
        if environ.get(var):
            settings[key] = environ[var]
    policy = settings.get("policy", "None")
    if policy not in POLICIES:
        raise IngestError(f"security policy {policy!r} is not one of {', '.join(POLICIES)}")
    if policy != "None":
        if settings.get("mode", "SignAndEncrypt") not in ("Sign", "SignAndEncrypt"):
            raise IngestError(f"security mode {settings['mode']!r} is not Sign or SignAndEncrypt")
        missing = [ENV[k] for k in ("certificate", "private_key") if not settings.get(k)]
        if missing:
            raise IngestError(f"security policy {policy} needs a client certificate and key ({', '.join(missing)})")
    if settings.get("password") and not settings.get("user"):
        raise IngestError("a password without a user (FEEDLOG_OPCUA_USER)")
    return settings


def _certificate_uri(path: str) -> str | None:
    """The application URI in a certificate's subjectAltName (the client must announce the same)."""
    from cryptography import x509

    data = Path(path).read_bytes()
    cert = x509.load_pem_x509_certificate(data) if data.lstrip().startswith(b"-----") else \
        x509.load_der_x509_certificate(data)
    try:
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName)
    except x509.ExtensionNotFound:
        return None
    uris = san.value.get_values_for_type(x509.UniformResourceIdentifier)
    return uris[0] if uris else None


async def _configure(client, settings: dict[str, str]) -> None:
    from asyncua import ua
    from asyncua.crypto import security_policies

    if settings.get("user"):
        client.set_user(settings["user"])
    if settings.get("password"):
        client.set_password(settings["password"])
    policy = settings.get("policy", "None")
    if policy == "None":
        return
    for key in ("certificate", "private_key", "server_certificate"):
        if settings.get(key) and not Path(settings[key]).is_file():
            raise IngestError(f"{key.replace('_', ' ')} file not found: {settings[key]}")
    try:
        uri = _certificate_uri(settings["certificate"])
    except (ValueError, OSError) as exc:
        raise IngestError(f"cannot load the client certificate: {exc}", file=settings["certificate"]) from None
    if uri:
        client.application_uri = uri
    try:
        await client.set_security(getattr(security_policies, f"SecurityPolicy{policy}"), settings["certificate"],
                                  settings["private_key"], settings.get("private_key_password") or None,
                                  settings.get("server_certificate") or None,
                                  getattr(ua.MessageSecurityMode, settings.get("mode", "SignAndEncrypt")))
    except (ValueError, TypeError) as exc:
        raise IngestError(f"cannot load the client certificate or key: {exc}") from None


def _connect_error(url: str, exc: BaseException, settings: dict[str, str]) -> IngestError:
    """One clear line for a failed connect."""
    from asyncua import ua

    name = type(exc).__name__
    if isinstance(exc, ua.UaStatusCodeError):
        code = ua.StatusCodes.__dict__
        name = next((k for k, v in code.items() if v == exc.code), name)
    if name in LOGIN_REFUSED:
        who = f"user {settings['user']!r}" if settings.get("user") else "anonymous login"
        return IngestError(f"the OPC UA server at {url} refused the login ({who}): {name}")
    if name in CERT_REFUSED:
        return IngestError(f"the OPC UA server at {url} refused the connection's security (is the client "
                           f"certificate trusted by the server?): {name}")
    if isinstance(exc, (asyncio.TimeoutError, TimeoutError)):
        return IngestError(f"the OPC UA server at {url} did not answer in time")
    if isinstance(exc, OSError):
        return IngestError(f"cannot reach the OPC UA server at {url}: {exc.strerror or exc}")
    if isinstance(exc, ua.UaError):
        return IngestError(f"OPC UA connection to {url} failed: {exc}")
    return IngestError(f"OPC UA connection to {url} failed: {name}: {exc}")


# -- which nodes --------------------------------------------------------------------------------------------
async def _child(node, name: str):
    for child in await node.get_children():
        if (await child.read_browse_name()).Name == name:
            return child
    return None


async def _find(node, name: str, depth: int):
    """A node with this browse name within `depth` levels below `node` (breadth first)."""
    level = [node]
    for _ in range(depth):
        nxt = []
        for parent in level:
            for child in await parent.get_children():
                if (await child.read_browse_name()).Name == name:
                    return child
                nxt.append(child)
        level = nxt[:500]
    return None


async def standard_layout(client) -> NodeMap | None:
    """The CNC / machine-tool layout's nodes (see the module docstring), None without CncInterface."""
    objects = client.nodes.objects
    cnc = await _find(objects, "CncInterface", 3)
    if cnc is None:
        return None
    nmap = NodeMap(name="cnc-layout", controller="OPC UA CNC interface (OPC 40502)", verified=True)
    axes = await _child(cnc, "CncAxisList")
    for axis in (await axes.get_children()) if axes is not None else []:
        letter = (await axis.read_browse_name()).Name.strip()[:1].lower()
        if letter not in AXES or letter in nmap.columns:
            continue
        pos = await _child(axis, "PosIndirect") or await _child(axis, "PosDirect")
        if pos is None:
            continue
        for child_name, target in (("ActPos", letter), ("CmdPos", f"{letter}_cmd")):
            var = await _child(pos, child_name)
            if var is not None:
                nmap.columns[target] = (var.nodeid.to_string(), None)
    channels = await _child(cnc, "CncChannelList")
    first = (await channels.get_children())[:1] if channels is not None else []
    for channel in first:
        for child_name, target in (("ActFeedrate", "feed"), ("CmdFeedrate", "requested_feed"), ("ActProgramLine", "line")):
            var = await _child(channel, child_name)
            if var is not None:
                nmap.columns[target] = (var.nodeid.to_string(), None)
        for child_name, event in (("ActProgramName", "program"), ("ActProgramStatus", "execution"),
                                  ("ToolId", "tool_number"), ("ActProgramBlock", "block")):
            var = await _child(channel, child_name)
            if var is not None:
                nmap.events[event] = var.nodeid.to_string()
    machines = await _child(objects, "Machines")
    for machine in (await machines.get_children())[:1] if machines is not None else []:
        state = await _find(machine, "ChannelState", 3)
        if state is not None:
            nmap.events["channel_state"] = state.nodeid.to_string()
    return nmap if nmap.columns else None


async def resolve_nodes(client, nmap: NodeMap) -> tuple[Plan, dict[str, Any]]:
    """Check every node of the map exists and read its units: (plan, node id -> asyncua Node)."""
    from asyncua import ua

    plan = Plan(nmap.name)
    nodes: dict[str, Any] = {}
    missing = []
    for target, (node_id, unit) in nmap.columns.items():
        try:
            node = client.get_node(node_id)
            await node.read_browse_name()
        except (ua.UaError, ValueError) as exc:
            missing.append(f"{target}={node_id} ({type(exc).__name__})")
            continue
        source = "map"
        if unit is None and target != "line":
            eu = await _child(node, "EngineeringUnits")
            unit = unit_from_eu(await eu.read_value()) if eu is not None else None
            source = "server"
        if unit is None and target != "line":
            unit = "mm/min" if target in ("feed", "requested_feed") else ("mm" if target[0] in "xyz" else "deg")
            source = "default"
        stream, column = TARGETS[target]
        if stream.startswith("axes"):
            column = f"{column}_{'mm' if column in 'xyz' else 'deg'}"
        try:
            factor = _unit_factor(target, unit or "")
        except IngestError as exc:
            raise IngestError(f"node {node_id}: {exc.message} (give unit = ... in the node map)") from None
        plan.columns[node_id] = Column(stream, column, factor)
        plan.labels[node_id] = f"{unit or 'number'} from {source}"
        nodes[node_id] = node
    for event, node_id in nmap.events.items():
        try:
            node = client.get_node(node_id)
            await node.read_browse_name()
        except (ua.UaError, ValueError):
            missing.append(f"events.{event}={node_id}")
            continue
        plan.events[node_id] = event
        nodes[node_id] = node
    if missing and not plan.columns:
        raise IngestError(f"none of the node map's nodes exist on the server ({', '.join(missing[:6])}); "
                          f"check the ids with an OPC UA browser")
    if missing:
        plan.notes.append(f"not on the server: {', '.join(missing)}")
    if not any(c.stream == "axes" for c in plan.columns.values()):
        plan.notes.append("no axis positions: align and diagnose use the line stream")
    return plan, nodes


# -- values -> observations ---------------------------------------------------------------------------------
_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


def to_ns(stamp) -> int | None:
    if not isinstance(stamp, dt.datetime):
        return None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=dt.UTC)
    if stamp.year < 1971:  # OPC UA's "no time" is 1601-01-01
        return None
    return (stamp - _EPOCH) // dt.timedelta(microseconds=1) * 1000


def value_text(value) -> str:
    """A variable's value as observation text (what `Pivot` parses or keeps as an event)."""
    if value is None:
        return "UNAVAILABLE"
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):  # ActProgramBlock: previous, actual, next block
        items = [value_text(v) for v in value]
        return items[len(items) // 2] if len(items) == 3 else " | ".join(items)
    text = getattr(value, "Text", None)  # LocalizedText
    if isinstance(text, str):
        return text
    if hasattr(value, "value") and isinstance(getattr(value, "value"), int):  # an enum
        return str(value.value)
    return str(value)


class _Handler:
    """asyncua subscription handler: collects (node id, value text, time, sequence)."""

    def __init__(self) -> None:
        self.items: list[Observation] = []
        self.times: list[int] = []
        self.sequence = 0
        self.bad_status = 0
        self.overflows = 0

    def datachange_notification(self, node, val, data) -> None:
        dv = data.monitored_item.Value
        t = to_ns(dv.ServerTimestamp) or to_ns(dv.SourceTimestamp)
        status = dv.StatusCode
        good = status is None or status.is_good() or status.is_uncertain()
        if status is not None and status.value & 0x480 == 0x480:   # InfoType DataValue, Overflow bit
            self.overflows += 1
        if not good:
            self.bad_status += 1
            if t is None:  # no server time: the client's own notice of a lost connection, not a value
                return
        t = t if t is not None else time.time_ns()
        self.sequence += 1
        self.items.append(Observation(node.nodeid.to_string(), self.sequence, "",
                                      value_text(val) if good else "UNAVAILABLE"))
        self.times.append(t)

    def mark_loss(self, reason: str) -> None:
        """A lost connection, in order with the values (a time of None marks it)."""
        self.items.append(Observation("", -1, "", reason))
        self.times.append(None)

    def take(self) -> list[tuple[str | None, list[Observation], np.ndarray]]:
        """What arrived since the last call: runs of (loss reason or None, values, times)."""
        items, times = self.items, self.times
        self.items, self.times = [], []
        runs: list[tuple[str | None, list[Observation], list[int]]] = [(None, [], [])]
        for obs, t in zip(items, times):
            if t is None:
                runs.append((obs.value, [], []))
            else:
                runs[-1][1].append(obs)
                runs[-1][2].append(t)
        return [(loss, obs, np.asarray(t, dtype=np.int64)) for loss, obs, t in runs]

    def status_change_notification(self, status) -> None:
        pass


# -- the recorder ---------------------------------------------------------------------------------------------
def _take(handler: _Handler, session: RowSession, resume: _Resume, stats: Stats) -> None:
    for loss, items, times in handler.take():
        if loss is not None:
            stats.reconnects += 1
            session.gap(Gap(-1, loss))
            resume.lost()
        resume.deliver(session, items, times)


class _Resume:
    """After a lost connection, the first value each monitored item reports is the server's current
    value (a re-created monitored item always starts with one), stamped when it last changed: it is
    the state where recording resumes, applied at the first newer value, not a change at its old time."""

    def __init__(self, items) -> None:
        self.items = set(items)
        self.awaiting: set[str] = set()

    def lost(self) -> None:
        self.awaiting = set(self.items)

    def deliver(self, session: RowSession, items: list[Observation], times: np.ndarray) -> None:
        if not len(items):
            return
        if self.awaiting:
            first = np.zeros(len(items), dtype=bool)
            for k, obs in enumerate(items):
                if obs.item in self.awaiting:
                    self.awaiting.discard(obs.item)
                    first[k] = True
            if first.any():
                session.state((session.resume_state or []) + [o for o, f in zip(items, first) if f])
                items = [o for o, f in zip(items, first) if not f]
                times = times[~first]
        if len(items):
            session.observations(items, times)


async def _record(url: str, out, *, nodes: str | None, settings: dict[str, str], interval_ms: int,
                  metadata: dict[str, str], attachments: dict[str, bytes], overwrite: bool, stop: threading.Event,
                  duration_s: float | None, progress: TextIO | None, connect_timeout_s: float) -> dict[str, Any]:
    from asyncua import Client, ua

    client = Client(url, timeout=connect_timeout_s, watchdog_intervall=1.0)
    client.application_uri = "urn:feedlog:recorder"
    await _configure(client, settings)
    try:
        # reconnects: tried again within 1 s, a request waits at most 2 s for one (a server that is still
        # starting up must not hold the recording for a whole timeout)
        await asyncio.wait_for(client.connect(auto_reconnect=True, reconnect_max_delay=1.0,
                                              reconnect_request_timeout=2.0), connect_timeout_s * 2)
    except (TimeoutError, OSError, ua.UaError) as exc:
        try:
            await asyncio.wait_for(client.disconnect(), 2)
        except Exception:  # noqa: BLE001 - half-open connections fail to close in many ways
            pass
        raise _connect_error(url, exc, settings) from None
    writer = None
    stats = Stats()
    stats.queue_overflows = 0  # values the server's queue dropped (the Overflow bit), shown in the summary
    stats.refused_nodes = []
    try:
        nmap = load_node_map(nodes) if nodes else await standard_layout(client)
        if nmap is None:
            raise IngestError(f"the OPC UA server at {url} has no CncInterface (OPC 40502 / 40501 layout): give a "
                              f"node map with --nodes ({', '.join(builtin_maps())} or a TOML file)")
        plan, node_objs = await resolve_nodes(client, nmap)
        meta = {"controller": nmap.controller or "opcua", "units": "mm, deg, mm/min",
                **{k: v for k, v in metadata.items() if v}, "source": "opcua", "server": url,
                "node_map": nmap.name, "node_map_verified": "true" if nmap.verified else "false (unverified on real hardware)",
                "interval_ms": str(interval_ms), "security": settings.get("policy", "None") + (
                    f" {settings.get('mode', 'SignAndEncrypt')}" if settings.get("policy", "None") != "None" else ""),
                "login": "user" if settings.get("user") else "anonymous", "nodes": plan.describe(),
                "start_time": iso(time.time_ns())}
        if plan.notes:
            meta["notes"] = "; ".join(filter(None, [meta.get("notes", ""), *plan.notes]))
        writer = RecordingWriter(out, metadata=meta, attachments=attachments, overwrite=overwrite,
                                 flush_interval_s=1.0, compression="lz4")
        session = RowSession(plan, writer, stats)
        handler = _Handler()
        async def on_lost(exc: Exception) -> None:  # in line with the values: those before it came before
            handler.mark_loss(f"connection lost ({type(exc).__name__})")

        client.connection_lost_callback = on_lost
        publish_ms = max(interval_ms, 100)
        subscription = await client.create_subscription(publish_ms, handler)
        # room on the server for 10 publishing intervals of samples: a late publish must not drop any
        queue = min(1000, max(50, 10 * -(-publish_ms // interval_ms)))
        results = await subscription.subscribe_data_change(list(node_objs.values()), queuesize=queue,
                                                           sampling_interval=float(interval_ms))
        refused = [nid for nid, r in zip(node_objs, results) if isinstance(r, ua.StatusCode)]
        if len(refused) == len(node_objs):
            raise IngestError(f"the OPC UA server refused to monitor every node ({refused[0]} ...)")
        stats.refused_nodes = refused  # monitored items the server would not create (in the summary)
        resume = _Resume(node_objs)
        show = Progress(progress)
        start, cpu0 = time.monotonic(), time.process_time()
        while True:
            stats.stopped_by = stop_reason(stop, duration_s, time.monotonic() - start)
            if stats.stopped_by:
                break
            await asyncio.sleep(0.1)
            _take(handler, session, resume, stats)
            session.release_due()
            writer.flush_if_due()
            stats.queue_overflows = handler.overflows
            show.show(stats, time.monotonic() - start)
        _take(handler, session, resume, stats)
        session.finish()
        stats.wall_s = time.monotonic() - start
        stats.cpu_s = round(time.process_time() - cpu0, 3)
        show.show(stats, stats.wall_s, final=True)
    except OutputError as exc:
        stats.error = str(exc)
        stats.stopped_by = "write error"
    finally:
        try:
            await asyncio.wait_for(client.disconnect(), 5)
        except Exception:  # noqa: BLE001 - the server may be gone: nothing left to close
            pass
        if writer is not None:
            try:
                writer.close()
            except OutputError as exc:
                stats.error = stats.error or str(exc)
                stats.stopped_by = "write error"
    summary = {"out": str(out), "server": url, **stats.as_dict()}
    summary.pop("sequences_lost", None)
    return summary


def record_server(url: str, out, *, nodes: str | None = None, security: str | None = None, interval_ms: int = 100,
                  metadata: dict[str, str] | None = None, attachments: dict[str, bytes] | None = None,
                  overwrite: bool = False, stop: threading.Event | None = None, duration_s: float | None = None,
                  progress: TextIO | None = sys.stderr, connect_timeout_s: float = 10.0,
                  environ=os.environ) -> dict[str, Any]:
    """Record an OPC UA server into a new recording `out`; returns a summary."""
    if not url.startswith("opc.tcp://") or len(url) <= len("opc.tcp://"):
        raise IngestError(f"bad OPC UA URL {url!r}: give opc.tcp://HOST:PORT (e.g. opc.tcp://192.168.1.20:4840)")
    if not 1 <= interval_ms <= 600_000:
        raise IngestError(f"--interval-ms {interval_ms} must be from 1 to 600000")
    settings = security_settings(security, environ)
    if nodes:
        load_node_map(nodes)  # a bad map is an error before any connection
    for name in ("asyncua", "asyncua.client", "asyncua.common", "asyncua.uaprotocol"):
        logging.getLogger(name).setLevel(logging.CRITICAL if not os.environ.get("FEEDLOG_OPCUA_DEBUG") else logging.INFO)  # its reconnect chatter is not the user's business
    try:
        return asyncio.run(_record(url, out, nodes=nodes, settings=settings, interval_ms=interval_ms,
                                   metadata=metadata or {}, attachments=attachments or {}, overwrite=overwrite,
                                   stop=stop or threading.Event(), duration_s=duration_s, progress=progress,
                                   connect_timeout_s=connect_timeout_s))
    except FeedlogError:
        raise
    except ModuleNotFoundError as exc:
        raise FeedlogError(f"--source opcua needs the asyncua package ({exc})") from None


def record(args: argparse.Namespace) -> dict[str, Any]:
    return record_from_args(args, record_server, "opcua", "opc.tcp://HOST:PORT", nodes=args.nodes,
                            security=args.security)
