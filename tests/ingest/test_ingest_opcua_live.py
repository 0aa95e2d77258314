"""`feedlog record --source opcua` against a real asyncua server in its own process (tests/ingest/opcua_test_server.py)
on 127.0.0.1, replaying a bundled LinuxCNC recording: the CNC / machine-tool layout, node maps (a custom
one and the shipped ones), a server killed and restarted mid-session, Basic256Sha256 with certificates
and a password, and the one-line errors."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.source_opcua import load_node_map, record_server, security_settings
from tests.ingest.live_helpers import stop_when_set, wait_for_rows, watch_then_kill
from tests.ingest.mtconnect_test_agent import replay_table

pytest.importorskip("asyncua")

ROOT = Path(__file__).resolve().parents[2]
RECORDING = ROOT / "recordings" / "pocket_f3000_p001.mcap"   # 6.8 s
LONG = ROOT / "recordings" / "mix_026.mcap"                  # 12 s
TABLE = replay_table(RECORDING, 100.0)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Served:
    def __init__(self, proc: subprocess.Popen, url: str, t0_ns: int) -> None:
        self.proc, self.url, self.t0_ns = proc, url, t0_ns
        self.done = threading.Event()
        threading.Thread(target=self._watch, daemon=True).start()

    def _watch(self) -> None:
        for line in self.proc.stdout:
            if line.startswith("DONE"):
                self.done.set()


def start_server(port: int, t0: str = "+1.5", *extra: str, recording: Path = RECORDING) -> Served:
    proc = subprocess.Popen([sys.executable, "-m", "tests.ingest.opcua_test_server", str(recording), str(port), t0,
                             *extra], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    if not line.startswith("READY"):
        proc.kill()
        pytest.fail(f"the OPC UA test server did not start: {line} {proc.stderr.read()[-2000:]}")
    _, url, t0_ns = line.split()
    return Served(proc, url, int(t0_ns))


@contextmanager
def server(*extra: str, port: int | None = None):
    served = start_server(port or free_port(), "+1.5", *extra)
    try:
        yield served
    finally:
        served.proc.kill()
        served.proc.wait(10)


def stop_when_done(served: Served, stop: threading.Event, extra_s: float = 0.7) -> None:
    stop_when_set(served.done, stop, extra_s)


def replay_at(t0_ns: int, t_ns: np.ndarray, tab: dict = TABLE) -> dict[str, np.ndarray]:
    k = np.searchsorted(tab["t_ns"] + t0_ns, t_ns, side="right") - 1
    assert (k >= 0).all()
    return {name: tab[name][k] for name in ("x", "y", "z", "feed", "line")}


def assert_matches(rec, t0_ns: int, *, outside: list[tuple[int, int]] = (), commanded: bool = True,
                   tab: dict = TABLE) -> None:
    """Recorded values equal the replay at their (server) times; every change outside `outside` is there."""
    axes = rec.streams["axes"]
    assert np.all(np.diff(axes["t_ns"].to_numpy()) > 0)
    before = axes["t_ns"].to_numpy() < t0_ns   # the server's initial values, from before the replay
    assert (axes[before].iloc[:, 1:].to_numpy() == 0).all()
    axes = axes[~before]
    t = axes["t_ns"].to_numpy()
    assert len(t) > 100
    want = replay_at(t0_ns, t, tab)
    for axis in "xyz":
        np.testing.assert_array_equal(axes[f"{axis}_mm"].to_numpy(), want[axis])
        if commanded:
            cmd = rec.streams["axes_commanded"]
            cmd = cmd[cmd["t_ns"] >= t0_ns]
            np.testing.assert_array_equal(cmd[f"{axis}_mm"].to_numpy(), replay_at(t0_ns, cmd["t_ns"].to_numpy(), tab)[axis])
    assert_matches_line(rec, t0_ns, tab)
    feed = rec.streams["feed"]
    feed = feed[feed["t_ns"] >= t0_ns]
    np.testing.assert_allclose(feed["feed_mm_min"].to_numpy(), replay_at(t0_ns, feed["t_ns"].to_numpy(), tab)["feed"],
                               rtol=1e-12)
    pos = np.stack([tab["x"], tab["y"], tab["z"]], axis=1)
    changed = np.concatenate(([False], np.any(pos[1:] != pos[:-1], axis=1)))
    times = tab["t_ns"][changed] + t0_ns
    for start, end in outside:
        times = times[(times <= start) | (times >= end)]
    missing = times[~np.isin(times, t)]
    assert not len(missing), f"{len(missing)} replayed changes missing, first at {(missing[0] - t0_ns) / 1e9:.3f} s"


def test_records_the_cnc_layout_exactly(tmp_path, capsys):
    out = tmp_path / "cnc.mcap"
    with server() as served:
        stop = threading.Event()
        stop_when_done(served, stop)
        summary = record_server(served.url, out, interval_ms=10, stop=stop, progress=None)
    assert summary["gaps"] == [] and summary["stopped_by"] == "signal" and summary["queue_overflows"] == 0
    rec = read_recording(out)
    assert_matches(rec, served.t0_ns)
    meta = rec.metadata
    assert meta["source"] == "opcua" and meta["server"] == served.url and meta["node_map"] == "cnc-layout"
    assert "mm/min from server" in meta["nodes"] and meta["security"] == "None" and meta["login"] == "anonymous"
    events = rec.streams["events"]
    assert set(events["name"]) >= {"program", "execution", "channel_state"}
    assert "replay.ngc" in events[events["name"] == "program"]["value"].tolist()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert {s["name"] for s in info["streams"]} >= {"axes", "axes_commanded", "feed", "line", "events"}


CUSTOM_MAP = """
name = "test-machine"
controller = "a test controller"
verified = true
[columns]
x = { node = "ns=2;s=Machine/X/Actual", unit = "mm" }
y = { node = "ns=2;s=Machine/Y/Actual", unit = "mm" }
z = "ns=2;s=Machine/Z/Actual"
feed = { node = "ns=2;s=Machine/PathFeed", unit = "mm/s" }
line = { node = "ns=2;i=4711" }
[events]
program = "ns=2;s=Machine/Program"
"""


def test_a_custom_node_map_with_units(tmp_path):
    path = tmp_path / "mill.toml"
    path.write_text(CUSTOM_MAP)
    out = tmp_path / "map.mcap"
    with server("--layout", str(path)) as served:
        stop = threading.Event()
        stop_when_done(served, stop)
        summary = record_server(served.url, out, nodes=str(path), interval_ms=10, stop=stop, progress=None)
    rec = read_recording(out)
    assert summary["gaps"] == [] and rec.metadata["node_map"] == "test-machine"
    assert rec.metadata["controller"] == "a test controller" and rec.metadata["node_map_verified"] == "true"
    axes = rec.streams["axes"]
    axes = axes[axes["t_ns"] >= served.t0_ns]
    want = replay_at(served.t0_ns, axes["t_ns"].to_numpy())
    np.testing.assert_array_equal(axes["x_mm"].to_numpy(), want["x"])
    # the server publishes mm/min values; the map declares mm/s: feedlog converts as told (x 60)
    feed = rec.streams["feed"]
    feed = feed[feed["t_ns"] >= served.t0_ns]
    np.testing.assert_allclose(feed["feed_mm_min"], 60 * replay_at(served.t0_ns, feed["t_ns"].to_numpy())["feed"])
    assert_matches_line(rec, served.t0_ns)


def assert_matches_line(rec, t0_ns: int, tab: dict = TABLE) -> None:
    line = rec.streams["line"]
    line = line[line["t_ns"] >= t0_ns]
    np.testing.assert_array_equal(line["line"].to_numpy(), replay_at(t0_ns, line["t_ns"].to_numpy(), tab)["line"])


@pytest.mark.parametrize("name", ["sinumerik", "heidenhain"])
def test_shipped_node_maps_record_a_server_with_their_node_ids(tmp_path, name):
    from importlib import resources

    shipped = resources.files("feedlog.ingest") / "opcua_nodes" / f"{name}.toml"
    assert "unverified" in shipped.read_text().lower()
    path = tmp_path / f"{name}.toml"
    path.write_text(shipped.read_text())
    out = tmp_path / f"{name}.mcap"
    with server("--layout", str(path)) as served:
        stop = threading.Event()
        stop_when_done(served, stop)
        record_server(served.url, out, nodes=name, interval_ms=10, stop=stop, progress=None)
    rec = read_recording(out)
    assert rec.metadata["node_map_verified"].startswith("false")
    assert_matches(rec, served.t0_ns)


def test_server_killed_and_restarted_is_one_gap_and_nothing_before_it_is_lost(tmp_path):
    out = tmp_path / "restart.mcap"
    port = free_port()
    first = start_server(port, recording=LONG)
    second = None
    result: dict = {}
    stop = threading.Event()
    thread = threading.Thread(target=lambda: result.update(
        record_server(first.url, out, interval_ms=10, stop=stop, progress=None)), daemon=True)
    try:
        thread.start()
        time.sleep(1.5 + 3.0)                      # 3 s into the 12 s replay
        first.proc.send_signal(signal.SIGKILL)
        first.proc.wait(10)
        killed_at = time.time_ns()
        time.sleep(0.5)
        second = start_server(port, str(first.t0_ns), recording=LONG)
        stop_when_done(second, stop)
        thread.join(90)
    finally:
        stop.set()
        for served in (first, second):
            if served is not None:
                served.proc.kill()
    assert not thread.is_alive() and result, "the recorder did not finish"
    assert len(result["gaps"]) == 1 and result["gaps"][0]["lost"] == -1 and result["reconnects"] >= 1
    rec = read_recording(out)
    gaps = rec.streams["gaps"]
    start, end = int(gaps["t_ns"].iloc[0]), int(gaps["end_t_ns"].iloc[0])
    assert start < killed_at < end, (start, killed_at, end)
    tab = replay_table(LONG, 100.0)
    assert_matches(rec, first.t0_ns, outside=[(start, end)], tab=tab)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert (t < start).sum() > 100 and (t > end).sum() > 100       # recorded before the kill and after the restart


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    """Server and client certificates made here (asyncua's generator): one client trusted, one not."""
    import asyncio

    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from cryptography.x509.oid import ExtendedKeyUsageOID

    d = tmp_path_factory.mktemp("certs")
    (d / "trusted").mkdir()

    async def make():
        await setup_self_signed_certificate(d / "server_key.pem", d / "server_cert.der", "urn:feedlog:test:server",
                                            "127.0.0.1", [ExtendedKeyUsageOID.SERVER_AUTH], {"commonName": "server"})
        for who in ("client", "stranger"):
            await setup_self_signed_certificate(d / f"{who}_key.pem", d / f"{who}_cert.der", f"urn:feedlog:{who}",
                                                socket.gethostname(), [ExtendedKeyUsageOID.CLIENT_AUTH],
                                                {"commonName": who})
    asyncio.run(make())
    (d / "trusted" / "client_cert.der").write_bytes((d / "client_cert.der").read_bytes())
    return d


def test_basic256sha256_with_certificates_and_a_password(tmp_path, certs, capsys):
    secret = "s3cret-Pa55"
    env = {"FEEDLOG_OPCUA_POLICY": "Basic256Sha256", "FEEDLOG_OPCUA_MODE": "SignAndEncrypt",
           "FEEDLOG_OPCUA_CERT": str(certs / "client_cert.der"), "FEEDLOG_OPCUA_KEY": str(certs / "client_key.pem"),
           "FEEDLOG_OPCUA_USER": "operator", "FEEDLOG_OPCUA_PASSWORD": secret}
    out = tmp_path / "secure.mcap"
    with server("--secure", str(certs), "--user", "operator", "--password", secret) as served:
        stop = threading.Event()
        threading.Timer(4.0, stop.set).start()
        summary = record_server(served.url, out, interval_ms=10, stop=stop, progress=None, environ=env)
        assert summary["samples"] > 50
        rec = read_recording(out)
        assert rec.metadata["security"] == "Basic256Sha256 SignAndEncrypt" and rec.metadata["login"] == "user"
        data = out.read_bytes()
        assert secret.encode() not in data and b"operator" not in data and b"client_key" not in data
        assert_matches_line(rec, served.t0_ns)

        argv = ["record", "--source", "opcua", "--url", served.url, "-o", str(tmp_path / "x.mcap")]
        for key, value in {**env, "FEEDLOG_OPCUA_PASSWORD": "wrong"}.items():
            os.environ[key] = value
        try:
            assert main(argv) == 2
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1 and "refused the login (user 'operator')" in err, err
            assert "wrong" not in err
            os.environ["FEEDLOG_OPCUA_PASSWORD"] = secret
            os.environ["FEEDLOG_OPCUA_CERT"] = str(certs / "stranger_cert.der")
            os.environ["FEEDLOG_OPCUA_KEY"] = str(certs / "stranger_key.pem")
            assert main(argv) == 2
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1 and "refused the connection's security" in err, err
        finally:
            for key in env:
                os.environ.pop(key, None)
    assert not (tmp_path / "x.mcap").exists()


def test_security_settings_from_a_file_and_the_environment(tmp_path):
    path = tmp_path / "sec.toml"
    path.write_text('policy = "Basic256Sha256"\ncertificate = "c.der"\nprivate_key = "k.pem"\nuser = "u"\n'
                    'password = "from-file"\n')
    settings = security_settings(str(path), {"FEEDLOG_OPCUA_PASSWORD": "from-env"})
    assert settings["password"] == "from-env" and settings["certificate"] == "c.der"
    path.write_text('policy = "Basic128Rsa15"\n')
    with pytest.raises(IngestError, match="not one of None, Basic256Sha256"):
        security_settings(str(path), {})
    path.write_text('policy = "Basic256Sha256"\n')
    with pytest.raises(IngestError, match="needs a client certificate and key"):
        security_settings(str(path), {})
    path.write_text('passwort = "x"\n')
    with pytest.raises(IngestError, match="unknown keys"):
        security_settings(str(path), {})


def test_one_line_errors(tmp_path, capsys):
    out = str(tmp_path / "x.mcap")

    def error(*argv: str) -> str:
        assert main(["record", "--source", "opcua", "-o", out, *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert "Traceback" not in err and len(err.splitlines()) == 1, err
        return err

    assert "cannot reach the OPC UA server" in error("--url", f"opc.tcp://127.0.0.1:{free_port()}")
    assert "bad OPC UA URL" in error("--url", "http://127.0.0.1:4840")
    assert "needs --url" in error()
    assert "no node map 'fanuc'" in error("--url", "opc.tcp://127.0.0.1:1", "--nodes", "fanuc")
    bad = tmp_path / "bad.toml"
    bad.write_text("[columns]\nx = 5\n")
    assert "give node =" in error("--url", "opc.tcp://127.0.0.1:1", "--nodes", str(bad))
    bad.write_text("[columns]\nw = 'ns=2;s=W'\n")
    assert "'w' is not one of" in error("--url", "opc.tcp://127.0.0.1:1", "--nodes", str(bad))
    bad.write_text("[columns]\nx = { node = 'ns=2;s=X', unit = 'furlong' }\n")
    assert "furlong" in error("--url", "opc.tcp://127.0.0.1:1", "--nodes", str(bad))
    path = tmp_path / "mill.toml"
    path.write_text(CUSTOM_MAP)
    with server("--layout", str(path)) as served:
        assert "has no CncInterface" in error("--url", served.url)
        other = tmp_path / "other.toml"
        other.write_text("[columns]\nx = 'ns=2;s=Nowhere/X'\n")
        assert "none of the node map's nodes exist" in error("--url", served.url, "--nodes", str(other))
    assert not Path(out).exists()
    assert load_node_map("sinumerik").verified is False


def test_kill_9_of_the_recorder_loses_at_most_about_one_second(tmp_path):
    out = tmp_path / "kill.mcap"
    with server_long() as served:
        proc = subprocess.Popen([sys.executable, "-m", "feedlog.cli", "record", "--source", "opcua", "--url", served.url,
                                 "--interval-ms", "10", "-o", str(out), "--quiet"], cwd=ROOT,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            wait_for_rows(out, proc, after_ns=served.t0_ns, rows=20)
            killed_at, on_disk, min_lag = watch_then_kill(out, proc)
        finally:
            proc.kill()
        assert not served.done.is_set(), "the replay ended before the kill"
    rec = read_recording(out, recover=True)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert t[-1] >= on_disk and (killed_at - t[-1]) - min_lag < 1.4e9
    axes = rec.streams["axes"]
    axes = axes[axes["t_ns"] >= served.t0_ns]
    tab = replay_table(LONG, 100.0)
    np.testing.assert_array_equal(axes["x_mm"].to_numpy(), replay_at(served.t0_ns, axes["t_ns"].to_numpy(), tab)["x"])


@contextmanager
def server_long():
    served = start_server(free_port(), "+1.5", recording=LONG)
    try:
        yield served
    finally:
        served.proc.kill()
        served.proc.wait(10)
