"""Outputs are written all or nothing (feedlog.atomic): a full disk ends in one error line, exit code 1 and
no output or temporary file; a symlink sitting where a temporary name or the output goes is never followed."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from feedlog import atomic
from feedlog.atomic import atomic_output, atomic_outputs
from feedlog.errors import OutputError

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 20_000  # bytes a process may write to one file: a "disk" that fills up early


def _full_disk() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def _feedlog(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "feedlog", *argv], cwd=cwd, capture_output=True, text=True,
                          preexec_fn=_full_disk, timeout=300)


def _one_line_exit_1(proc: subprocess.CompletedProcess, command: str) -> str:
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"feedlog {command}: error: "), proc.stderr
    return lines[0]


def test_import_on_a_full_disk_leaves_nothing(tmp_path):
    trace = tmp_path / "trace.csv"
    trace.write_text("time,X1_ActualPosition,Y1_ActualPosition,Z1_ActualPosition,PathVelocity\n"
                     + "".join(f"{k},{k * 1e-3:.4f},{k * 2e-3:.4f},-1,3000\n" for k in range(20_000)))
    message = _one_line_exit_1(_feedlog("import", str(trace), "--preset", "servo-trace-1khz", "-o", "rec.mcap",
                                        cwd=tmp_path), "import")
    assert "rec.mcap" in message and "nothing was written" in message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trace.csv"]


def test_sim_on_a_full_disk_writes_neither_table(tmp_path):
    program = ROOT / "examples" / "pocket.ngc"
    message = _one_line_exit_1(_feedlog("sim", str(program), "--profile", "linuxcnc-xyz", "--out", "series.parquet",
                                        "--blocks-out", "blocks.parquet", cwd=tmp_path), "sim")
    assert "nothing was written" in message
    assert list(tmp_path.iterdir()) == []


def test_align_on_a_full_disk_leaves_no_folder(tmp_path):
    recording = ROOT / "recordings" / "test_p001.mcap"
    message = _one_line_exit_1(_feedlog("align", str(recording), "-o", "out", "-j", "1", "-q", cwd=tmp_path), "align")
    assert "nothing was written" in message
    assert list((tmp_path / "out").iterdir()) == []  # no test_p001/ with one or two of its three files


def test_an_error_while_writing_removes_the_temporary_files(tmp_path):
    with pytest.raises(RuntimeError, match="halfway"):
        with atomic_outputs(tmp_path / "a.parquet", tmp_path / "b.json") as (a, b):
            a.write_bytes(b"first")
            raise RuntimeError("halfway")
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "keep.json").write_text("old")
    with pytest.raises(OutputError, match=r"keep\.json: cannot write the output \(No such file"):
        with atomic_output(tmp_path / "keep.json") as temporary:
            temporary.unlink()  # the write "fails": the temporary file is gone when it is renamed
    assert (tmp_path / "keep.json").read_text() == "old"  # the earlier output is untouched


def test_a_symlink_at_the_temporary_name_is_never_followed(tmp_path, monkeypatch):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    names = iter(["aaaa", "bbbb"])
    monkeypatch.setattr(atomic.secrets, "token_hex", lambda n: next(names))
    (tmp_path / "out.json.aaaa.partial").symlink_to(victim)  # planted where the first temporary name goes
    with atomic_output(tmp_path / "out.json") as temporary:
        assert temporary.name == "out.json.bbbb.partial"
        temporary.write_text("new")
    assert victim.read_text() == "precious" and (tmp_path / "out.json").read_text() == "new"


def test_a_symlink_at_the_output_is_replaced_not_written_through(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "out.json"
    out.symlink_to(victim)
    with atomic_output(out) as temporary:
        temporary.write_text("new")
    assert victim.read_text() == "precious" and not out.is_symlink() and out.read_text() == "new"


# --- issue #30: every output place can fail with one error line, exit code 1 and nothing written ---------------

def _feedlog_plain(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "feedlog", *argv], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_record_without_an_output_is_a_usage_error(tmp_path):
    proc = _feedlog_plain("record", "--source", "sim", str(ROOT / "examples" / "pocket.ngc"), "--profile",
                          "linuxcnc-xyz", cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "feedlog record: error: the following arguments are required: -o/--out"
    assert list(tmp_path.iterdir()) == []


def test_record_onto_a_full_disk_leaves_no_file(tmp_path):
    def no_room() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))  # not even the recording's header fits

    proc = subprocess.run([sys.executable, "-m", "feedlog", "record", "--source", "sim",
                           str(ROOT / "examples" / "pocket.ngc"), "--profile", "linuxcnc-xyz", "--speedup", "50",
                           "-o", "rec.mcap"], cwd=tmp_path, capture_output=True, text=True, preexec_fn=no_room,
                          timeout=300)
    message = _one_line_exit_1(proc, "record")
    assert "rec.mcap" in message and "nothing was written" in message
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def aligned_two(tmp_path_factory) -> Path:
    """align's output for one training and one held-out bundled recording (what `train` reads)."""
    from feedlog.cli import main

    out = tmp_path_factory.mktemp("aligned") / "aligned"
    recordings = [str(ROOT / "recordings" / f"{name}.mcap") for name in ("corners_f3000_p001", "test_p001")]
    assert main(["align", *recordings, "-o", str(out), "-j", "1", "-q"]) == 0
    return out


def _commands(aligned: Path, out: str) -> dict[str, list[str]]:
    """One command per output-writing stage, its output at `out` (a folder, or a file in it for view)."""
    recording = str(ROOT / "recordings" / "test_p001.mcap")
    return {
        "align": ["align", recording, "-o", out, "-j", "1", "-q"],
        "sim": ["sim", str(ROOT / "examples" / "pocket.ngc"), "--profile", "linuxcnc-xyz", "-o", out, "-j", "1", "-q"],
        "train": ["train", str(aligned), "-o", out, "--models", "mlp", "--preset", "quick", "-j", "1", "-q"],
        "view": ["view", recording, "--save", str(Path(out) / "view.rrd")],
    }


@pytest.mark.parametrize("command", ["align", "sim", "train", "view"])
def test_a_file_where_the_output_folder_goes(command, aligned_two, tmp_path):
    (tmp_path / "existing.mcap").write_bytes(b"precious")
    proc = _feedlog_plain(*_commands(aligned_two, "existing.mcap")[command], cwd=tmp_path)
    message = _one_line_exit_1(proc, command)
    assert "existing.mcap" in message and "not a folder" in message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["existing.mcap"]
    assert (tmp_path / "existing.mcap").read_bytes() == b"precious"


@pytest.mark.parametrize("command", ["align", "sim", "train", "view"])
def test_a_read_only_output_place(command, aligned_two, tmp_path, monkeypatch, capsys):
    """A read-only file system (EROFS) under `ro/` (tests run as root, whom chmod does not stop): every
    creation of a file or folder there fails as the kernel would fail it."""
    import errno
    import os

    from feedlog.cli import main

    ro = tmp_path / "ro"
    ro.mkdir()
    prefix = str(ro)

    def refuse(real):
        def call(path, *args, **kwargs):
            if os.path.abspath(os.fsdecode(path)).startswith(prefix):
                raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fsdecode(path))
            return real(path, *args, **kwargs)
        return call

    monkeypatch.setattr(os, "open", refuse(os.open))
    monkeypatch.setattr(os, "mkdir", refuse(os.mkdir))
    code = main(_commands(aligned_two, str(ro / "out"))[command])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and err[0].startswith(f"feedlog {command}: error: "), err
    assert "Read-only file system" in err[0]
    assert list(ro.iterdir()) == []


def test_view_save_on_a_full_disk_leaves_nothing(tmp_path):
    recording = ROOT / "recordings" / "test_p001.mcap"
    message = _one_line_exit_1(_feedlog("view", str(recording), "--save", "v.rrd", cwd=tmp_path), "view")
    assert "v.rrd" in message and "nothing was written" in message
    assert list(tmp_path.iterdir()) == []
