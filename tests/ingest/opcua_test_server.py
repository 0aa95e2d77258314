"""An OPC UA server for tests (asyncua's server, run as its own process on 127.0.0.1), publishing a bundled
feedlog recording replayed at its own pace (100 Hz; a value is written only when it changes, stamped
with its replay time as server and source timestamp).

    python -m tests.ingest.opcua_test_server REC.mcap|synthetic:SECONDS PORT T0_NS [--layout cnc|MAP.toml]
        [--user U --password P] [--secure CERT_DIR]

`--layout cnc` (default) builds the OPC UA CNC interface (OPC 40502) with the machine-tool layout's
(OPC 40501) `Machines/<m>/Monitoring/<channel>/ChannelState`; a node map builds a variable for every
node id of the map (so a map can be tested the way the recorder reads it). `T0_NS` is the epoch time of
the replay's first sample (`+S`: S seconds after the server is ready): a server restarted with the
same T0 goes on where the replay is by then.
`--secure DIR` takes DIR/server_cert.der and DIR/server_key.pem, offers only Basic256Sha256
SignAndEncrypt and trusts the client certificates in DIR/trusted/. Prints `READY opc.tcp://... T0_NS`
once serving and `DONE` when the replay has ended.
"""

from __future__ import annotations

import argparse
import asyncio
import datetime as dt
import logging
import time
import tomllib
from pathlib import Path

import numpy as np
from asyncua import Server, ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions

from tests.ingest.mtconnect_test_agent import replay_table, synthetic_table

MM_MIN = ua.EUInformation(NamespaceUri="http://www.opcfoundation.org/UA/units/un/cefact", UnitId=4732977,
                          DisplayName=ua.LocalizedText("mm/min"), Description=ua.LocalizedText("millimetre per minute"))
DEG = ua.EUInformation(NamespaceUri="http://www.opcfoundation.org/UA/units/un/cefact", UnitId=17476,
                       DisplayName=ua.LocalizedText("deg"), Description=ua.LocalizedText("degree"))
MM = ua.EUInformation(NamespaceUri="http://www.opcfoundation.org/UA/units/un/cefact", UnitId=5066068,
                      DisplayName=ua.LocalizedText("mm"), Description=ua.LocalizedText("millimetre"))


class Users:
    def __init__(self, user: str, password: str) -> None:
        self.user, self.password = user, password

    def get_user(self, iserver, username=None, password=None, certificate=None):
        if username == self.user and password == self.password:
            return User(role=UserRole.User)
        return None


def values_at(tab: dict, i: int) -> dict[str, object]:
    """target -> value of replay sample i (what each kind of node publishes)."""
    axes = {a: float(tab[a][i]) for a in "xyzabc" if a in tab}
    return {**axes, **{f"{a}_cmd": v for a, v in axes.items()}, "feed": float(tab["feed"][i]),
            "requested_feed": 3000.0, "line": int(tab["line"][i]), "program": "replay.ngc",
            "execution": 1, "tool_number": 1, "block": f"N{int(tab['line'][i])}", "channel_state": 1}


async def build_cnc(server: Server, letters: str = "XYZ") -> dict[str, object]:
    idx = await server.register_namespace("http://opcfoundation.org/UA/CNC")
    tool_idx = await server.register_namespace("http://opcfoundation.org/UA/MachineTool/")
    objects = server.nodes.objects
    cnc = await objects.add_object(idx, "CncInterface")
    axes = await cnc.add_object(idx, "CncAxisList")
    nodes: dict[str, object] = {}
    for letter in letters:
        axis = await axes.add_object(idx, letter)
        pos = await axis.add_variable(idx, "PosIndirect", 0.0)
        for name, target in (("ActPos", letter.lower()), ("CmdPos", f"{letter.lower()}_cmd")):
            var = await pos.add_variable(idx, name, 0.0)
            await var.add_property(idx, "EngineeringUnits", MM if letter in "XYZ" else DEG)
            nodes[target] = var
    channels = await cnc.add_object(idx, "CncChannelList")
    channel = await channels.add_object(idx, "Channel_1")
    feed = await channel.add_variable(idx, "ActFeedrate", 0.0)
    await feed.add_property(idx, "EngineeringUnits", MM_MIN)
    nodes["feed"] = feed
    nodes["line"] = await channel.add_variable(idx, "ActProgramLine", "", varianttype=ua.VariantType.String)
    nodes["program"] = await channel.add_variable(idx, "ActProgramName", "", varianttype=ua.VariantType.String)
    nodes["execution"] = await channel.add_variable(idx, "ActProgramStatus", 0, varianttype=ua.VariantType.Int32)
    machines = await objects.add_object(tool_idx, "Machines")
    mill = await machines.add_object(tool_idx, "Mill")
    monitoring = await mill.add_object(tool_idx, "Monitoring")
    ch = await monitoring.add_object(tool_idx, "Channel_1")
    nodes["channel_state"] = await ch.add_variable(tool_idx, "ChannelState", 0, varianttype=ua.VariantType.Int32)
    return nodes


async def build_map(server: Server, path: Path) -> dict[str, object]:
    data = tomllib.loads(path.read_text())
    await server.register_namespace("urn:feedlog:test:nc")   # namespace 2, as the maps expect
    objects = server.nodes.objects
    nodes: dict[str, object] = {}
    entries = {**{t: (e if isinstance(e, str) else e["node"]) for t, e in data["columns"].items()},
               **data.get("events", {})}
    for target, node_id in entries.items():
        nid = ua.NodeId.from_string(node_id)
        initial = "" if target in ("program", "block") else (0 if target in ("line", "execution", "tool_number") else 0.0)
        vtype = {str: ua.VariantType.String, int: ua.VariantType.Int32, float: ua.VariantType.Double}[type(initial)]
        nodes[target] = await objects.add_variable(nid, f"{nid.NamespaceIndex}:{target}", initial, varianttype=vtype)
    return nodes


async def replay(server: Server, nodes: dict[str, object], tab: dict, t0_ns: int, *, cnc: bool) -> None:
    last: dict[str, object] = {}
    n = len(tab["t_ns"])
    # a server (re)started after T0 publishes the current values, not what it never saw
    i = max(0, int(np.searchsorted(tab["t_ns"] + t0_ns, time.time_ns(), side="right")) - 1)
    while i < n:
        due = t0_ns + int(tab["t_ns"][i])
        now_ns = time.time_ns()
        if now_ns < due:
            await asyncio.sleep(min(0.005, (due - now_ns) / 1e9))
            continue
        stamp = dt.datetime.fromtimestamp(due // 1000 / 1e6, dt.UTC)
        for target, value in values_at(tab, i).items():
            node = nodes.get(target)
            if node is None:
                continue
            if cnc and target == "line":
                value = str(value)
            if last.get(target) == value:
                continue
            last[target] = value
            vtype = (ua.VariantType.String if isinstance(value, str) else
                     ua.VariantType.Int32 if isinstance(value, int) else ua.VariantType.Double)
            await server.write_attribute_value(node.nodeid, ua.DataValue(ua.Variant(value, vtype), SourceTimestamp=stamp,
                                                                         ServerTimestamp=stamp))
        i += 1


async def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("recording")
    parser.add_argument("port", type=int)
    parser.add_argument("t0_ns", help="epoch ns of the replay's first sample, or +SECONDS after the server is ready")
    parser.add_argument("--layout", default="cnc")
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--user")
    parser.add_argument("--password")
    parser.add_argument("--secure")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    server = Server(user_manager=Users(args.user, args.password) if args.user else None)
    await server.init()
    url = f"opc.tcp://127.0.0.1:{args.port}"
    server.set_endpoint(url)
    server.set_server_name("feedlog test server")
    if args.secure:
        certs = Path(args.secure)
        await server.load_certificate(str(certs / "server_cert.der"))
        await server.load_private_key(str(certs / "server_key.pem"))
        server.set_security_policy([ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt])
        store = TrustStore([certs / "trusted"], [])
        await store.load()
        server.set_certificate_validator(CertificateValidator(
            CertificateValidatorOptions.TRUSTED_VALIDATION | CertificateValidatorOptions.PEER_CLIENT, store))
    else:
        server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
    if args.user:
        server.set_security_IDs(["Username"])
    cnc = args.layout == "cnc"
    if args.recording.startswith("synthetic:"):   # six axes at 100 Hz (benchmarks)
        tab = synthetic_table(float(args.recording.split(":", 1)[1]), args.rate_hz)
    else:
        tab = replay_table(Path(args.recording), args.rate_hz)
    letters = "".join(a.upper() for a in "xyzabc" if a in tab)
    nodes = await (build_cnc(server, letters) if cnc else build_map(server, Path(args.layout)))
    async with server:
        t0_ns = int(args.t0_ns) if not args.t0_ns.startswith("+") else \
            (time.time_ns() // 1_000_000 + int(float(args.t0_ns) * 1000)) * 1_000_000
        print(f"READY {url} {t0_ns}", flush=True)
        await replay(server, nodes, tab, t0_ns, cnc=cnc)
        print("DONE", flush=True)
        while True:
            await asyncio.sleep(1)


if __name__ == "__main__":
    asyncio.run(main())
