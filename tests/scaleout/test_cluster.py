"""align and sim on a real Dask cluster (`dask scheduler` + `dask worker` processes on 127.0.0.1) give the
same outputs as a local run, read by pandas, dask and duckdb as one table; a worker killed mid-job
does not change the result."""

from __future__ import annotations

import json
import shutil
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from tests.scaleout.cluster import dask_cluster, feedlog, kill_worker, same_outputs

ROOT = Path(__file__).resolve().parents[2]
RECORDINGS = ["test_p001", "mix5ax_000", "circle_f1000_p01", "mix_001"]   # three- and five-axis
KILL_SET = ["test_p001", "test_p01", "test_g61", "mix_000", "mix_001", "mix_002", "mix_003", "mix_004",
            "mix_005", "mix_006", "mix_007", "mix_008", "mix5ax_000", "mix5ax_001", "mix5ax_002", "mix5ax_004"]

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]


def client_dir(tmp: Path, names: list[str], *, broken: bool = False) -> Path:
    """A client working directory with recordings/ (relative paths on the command line) and programs/."""
    client = tmp / "client"
    (client / "recs").mkdir(parents=True)
    (client / "progs").mkdir()
    for name in names:
        shutil.copy(ROOT / "recordings" / f"{name}.mcap", client / "recs")
        shutil.copy(ROOT / "recordings" / "programs" / f"{name}.ngc", client / "progs")
    if broken:
        (client / "recs" / "broken.mcap").write_bytes(b"\x89MCAP0\r\n truncated")
        (client / "progs" / "broken.ngc").write_text("G21 G90\nG1 X10 F1000\nG5.3 X1\nM2\n")
    return client


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    with dask_cluster(tmp_path_factory.mktemp("cluster")) as (address, workers):
        yield address


def test_align_on_cluster_same_as_local(cluster, tmp_path):
    client = client_dir(tmp_path, RECORDINGS, broken=True)
    recs = [f"recs/{n}.mcap" for n in RECORDINGS] + ["recs/broken.mcap"]
    local = feedlog("align", *recs, "-o", "local", "-j", "1", "-q", cwd=client)
    remote = feedlog("align", *recs, "-o", "remote", "-q", "--scheduler", cluster, cwd=client)
    assert local.returncode == remote.returncode == 0, remote.stderr   # broken.mcap is refused, the rest is written
    assert "Dask: 2 worker(s)" in remote.stderr and "dashboard" in remote.stderr
    for res in (local, remote):
        assert "warning: recs/broken.mcap: " in res.stderr and f"{len(RECORDINGS)} aligned, 1 refused" in res.stdout
        assert res.stdout.count("cycle time") == len(RECORDINGS)
    assert same_outputs(client / "local", client / "remote") == []
    assert sorted(p.name for p in (client / "remote").iterdir()) == sorted(RECORDINGS + ["dataset"])
    assert not [p for p in (client / "remote").rglob(".*")], "partial outputs left behind"

    # one table: pandas, dask and duckdb read the dataset; it holds the per-recording tables
    import dask.dataframe as dd

    blocks = pd.read_parquet(client / "remote" / "dataset" / "blocks")
    points = dd.read_parquet(str(client / "remote" / "dataset" / "points")).compute()
    assert sorted(blocks["recording"].unique()) == sorted(RECORDINGS)
    for name in RECORDINGS:
        own = pd.read_parquet(client / "remote" / name / "blocks.parquet")
        part = blocks[blocks["recording"] == name].drop(columns="recording").reset_index(drop=True)
        pd.testing.assert_frame_equal(part, own, check_dtype=False, check_categorical=False)
        assert (points["recording"] == name).sum() == len(pd.read_parquet(client / "remote" / name / "points.parquet"))
    five = points[points["recording"] == "mix5ax_000"]
    assert five["va_meas_deg_min"].notna().all() and points.loc[points["recording"] == "test_p001",
                                                                "va_meas_deg_min"].isna().all()
    duckdb = pytest.importorskip("duckdb")
    glob = str(client / "remote" / "dataset" / "blocks" / "*" / "*.parquet")
    rows = duckdb.sql(f"SELECT recording, sum(duration_s) FROM read_parquet('{glob}', hive_partitioning=true) "
                      "GROUP BY recording").fetchall()
    cycle = {r: s for r, s in rows}
    for name in RECORDINGS:
        assert cycle[name] == pytest.approx(blocks.loc[blocks["recording"] == name, "duration_s"].sum())


def test_sim_on_cluster_same_as_local(cluster, tmp_path):
    client = client_dir(tmp_path, RECORDINGS, broken=True)
    progs = [f"progs/{n}.ngc" for n in RECORDINGS] + ["progs/broken.ngc"]
    local = feedlog("sim", *progs, "--profile", "linuxcnc-xyzac", "-o", "local", "-j", "1", "-q", cwd=client)
    remote = feedlog("sim", *progs, "--profile", "linuxcnc-xyzac", "-o", "remote", "-q", "--scheduler", cluster,
                     cwd=client)
    assert local.returncode == remote.returncode == 2
    assert "progs/broken.ngc" in remote.stderr and "G5.3" in remote.stderr
    assert same_outputs(client / "local", client / "remote") == []
    series = pd.read_parquet(client / "remote" / "dataset" / "series")
    assert sorted(series["program"].unique()) == sorted(RECORDINGS)


def test_urls_in_and_out(cluster, tmp_path):
    client = client_dir(tmp_path, RECORDINGS[:2])
    recs = [(client / "recs" / f"{n}.mcap").as_uri() for n in RECORDINGS[:2]]
    out = (tmp_path / "by-url").as_uri()
    remote = feedlog("align", *recs, "-o", out, "-q", "--scheduler", cluster, cwd=client)
    assert remote.returncode == 0, remote.stderr
    local = feedlog("align", *recs, "-o", "local", "-j", "1", "-q", cwd=client)
    assert local.returncode == 0, local.stderr
    assert same_outputs(client / "local", tmp_path / "by-url") == []


def test_worker_killed_mid_job(tmp_path):
    client = client_dir(tmp_path, KILL_SET)
    recs = [f"recs/{n}.mcap" for n in KILL_SET]
    local = feedlog("align", *recs, "-o", "local", "-j", "1", "-q", cwd=client)
    assert local.returncode == 0, local.stderr
    with dask_cluster(tmp_path / "cluster", workers=2) as (address, workers):
        killed: list[tuple[int, list[str]]] = []   # (recordings published, tasks w0 was running) at the kill

        def kill_mid_task() -> None:
            from distributed import Client

            with Client(address, timeout=120) as watcher:
                deadline = time.monotonic() + 300
                while time.monotonic() < deadline and not killed:
                    addr = next((a for a, w in watcher.scheduler_info()["workers"].items() if w["name"] == "w0"), None)
                    running = list(watcher.processing(workers=[addr]).get(addr, [])) if addr else []
                    done = list((client / "remote").glob("*/report.json"))
                    if done and running:  # the job is under way and w0 is inside a task
                        kill_worker(workers[0])
                        killed.append((len(done), [str(k) for k in running]))
                    time.sleep(0.01)

        thread = threading.Thread(target=kill_mid_task)
        thread.start()
        remote = feedlog("align", *recs, "-o", "remote", "-q", "--scheduler", address, cwd=client)
        thread.join()
    assert killed and killed[0][0] < len(KILL_SET) and killed[0][1], "the worker was not killed inside a task"
    assert workers[0].returncode is not None
    assert remote.returncode == 0, remote.stderr
    assert same_outputs(client / "local", client / "remote") == []
    assert not [p for p in (client / "remote").rglob(".*")], "partial outputs left behind"


def test_demo_on_cluster_same_table(cluster, tmp_path):
    client = client_dir(tmp_path, RECORDINGS[:3])
    args = ["demo", "--recordings", "recs", "--no-train", "--json", "--detail-plots", "0"]
    local = feedlog(*args, "--out", "local", "-j", "1", cwd=client)
    remote = feedlog(*args, "--out", "remote", "--scheduler", cluster, cwd=client)
    assert local.returncode == remote.returncode == 0, remote.stderr
    assert "Dask: 2 worker(s)" in remote.stderr
    rows = json.loads(remote.stdout)
    assert rows == json.loads(local.stdout) and len(rows) == 3
    assert all(r["measured_s"] and r["sim_s"] for r in rows)


def test_diagnose_on_cluster_same_as_local(cluster, tmp_path):
    client = tmp_path / "client"
    client.mkdir()
    for f in sorted((ROOT / "recordings" / "mystery").glob("*.mcap")):
        shutil.copy(f, client)
    recs = sorted(p.name for p in client.glob("*.mcap"))
    local = feedlog("diagnose", *recs, "--profile", "linuxcnc-xyz", "--json", "--no-learned", "-j", "1", cwd=client)
    remote = feedlog("diagnose", *recs, "--profile", "linuxcnc-xyz", "--json", "--no-learned", "--scheduler", cluster,
                     cwd=client)
    assert local.returncode == remote.returncode == 0, remote.stderr
    a, b = json.loads(local.stdout), json.loads(remote.stdout)
    assert a["findings"] and a["findings"] == b["findings"]   # fitted values, intervals, folds: identical
    assert a["error_after_pct"] == b["error_after_pct"]
