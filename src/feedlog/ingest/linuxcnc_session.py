"""Start LinuxCNC headless on one program with feedlog's driver and recorder, and collect what it wrote.

The machine INI is copied into a private work directory with two changes: `[DISPLAY] DISPLAY` names
our driver (linuxcnc_driver.py, run by Debian's python3) and the recorder haltcl file
(linuxcnc_hal.recorder_tcl) replaces the INI's recording HALFILE (one named `record*.tcl`) or is
appended after the last HALFILE. Relative HALFILE/TOOL_TABLE paths keep pointing at the INI's folder.

As root, `rtapi_app` needs `RTAPI_UID` (a non-root uid) and `RTAPI_FIFO_PATH` in a folder that uid can
write. `isolate=True` runs the whole stack in private IPC/PID/mount/net/UTS namespaces with its own
/tmp, so several sessions (or a teammate's) never share LinuxCNC's shared memory, lock file or port.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import shlex
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from feedlog.errors import FeedlogError, IngestError, ProgramError
from feedlog.ingest.linuxcnc_hal import ENABLE_SIGNAL, MOTION_TIME_COMPONENT, SamplerLayout, recorder_tcl, \
    standard_layout

DRIVER_SOURCE = Path(__file__).with_name("linuxcnc_driver.py")
DEBIAN_PYTHON = "/usr/bin/python3"
NOBODY_UID = 65534
_SECTION = re.compile(r"^\s*\[([^\]]+)\]\s*$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_]+)\s*=\s*(.*?)\s*$")
_LINE_IN_TEXT = re.compile(r"(?:on|near) line (\d+)", re.IGNORECASE)


@dataclass(frozen=True)
class MachineIni:
    """The parts of a LinuxCNC INI the recorder needs (all values as written, first occurrence)."""

    path: Path
    text: str
    values: dict[tuple[str, str], list[str]] = field(default_factory=dict)

    @classmethod
    def read(cls, path: str | os.PathLike) -> MachineIni:
        p = Path(path)
        try:
            text = p.read_bytes().decode("utf-8-sig")
        except OSError as exc:
            raise IngestError(f"cannot read LinuxCNC INI: {exc.strerror}", file=str(p)) from None
        except UnicodeDecodeError as exc:
            raise IngestError(f"LinuxCNC INI is not UTF-8 text (byte {exc.start})", file=str(p),
                              position=f"byte {exc.start}") from None
        values: dict[tuple[str, str], list[str]] = {}
        section = ""
        for raw in text.splitlines():
            line = raw.split("#", 1)[0] if raw.lstrip().startswith("#") else raw
            m = _SECTION.match(line)
            if m:
                section = m.group(1).strip().upper()
                continue
            m = _KEY.match(line)
            if m and section:
                values.setdefault((section, m.group(1).upper()), []).append(m.group(2))
        ini = cls(path=p.resolve(), text=text, values=values)
        for key in (("TRAJ", "COORDINATES"), ("KINS", "JOINTS"), ("EMCMOT", "SERVO_PERIOD")):
            if ini.get(*key) is None:
                raise IngestError(f"LinuxCNC INI lacks [{key[0]}] {key[1]}", file=str(p))
        ini.joints, ini.servo_period_ns  # noqa: B018 - each raises IngestError now if unusable, not mid-session
        if not any(c.isalpha() for c in ini.coordinates):
            raise IngestError(f"[TRAJ] COORDINATES {ini.coordinates!r} names no axis", file=str(p))
        return ini

    def _number(self, section: str, key: str, kind, low: float, high: float):
        raw = str(self.get(section, key))
        try:
            value = kind(float(raw)) if kind is not int else int(raw)
        except (ValueError, OverflowError):
            value = None
        if value is None or not low <= value <= high:
            raise IngestError(f"[{section}] {key} = {raw!r} is not a {'whole ' if kind is int else ''}number "
                              f"from {low:g} to {high:g}", file=str(self.path))
        return value

    def get(self, section: str, key: str) -> str | None:
        found = self.values.get((section.upper(), key.upper()))
        return found[0] if found else None

    @property
    def coordinates(self) -> str:
        return str(self.get("TRAJ", "COORDINATES")).replace(" ", "").upper()

    @property
    def joints(self) -> int:
        return self._number("KINS", "JOINTS", int, 1, 16)  # LinuxCNC's EMCMOT_MAX_JOINTS

    @property
    def servo_period_ns(self) -> int:
        return self._number("EMCMOT", "SERVO_PERIOD", int, 1_000, 1_000_000_000)

    @property
    def linear_units(self) -> str:
        return (self.get("TRAJ", "LINEAR_UNITS") or "mm").strip()

    def hal_files(self) -> list[Path]:
        """The machine's own HAL files that exist (not LIB: ones, not the recording HALFILE)."""
        found = []
        for value in self.values.get(("HAL", "HALFILE"), []):
            first = value.split()[0] if value.split() else ""
            if not first or first.startswith("LIB:") or re.match(r"record.*\.tcl$", Path(first).name):
                continue
            path = Path(first) if Path(first).is_absolute() else self.path.parent / first
            if path.is_file():
                found.append(path)
        return found

    def layout(self) -> SamplerLayout:
        try:
            return standard_layout(self.coordinates, self.joints)
        except ValueError as exc:  # more axes and joints than the samplers hold
            raise IngestError(f"cannot record this machine: {exc}", file=str(self.path)) from None

    def subroutine_dirs(self) -> list[Path]:
        """The folders of [RS274NGC] SUBROUTINE_PATH (colon-separated; relative to the INI's folder)."""
        value = self.get("RS274NGC", "SUBROUTINE_PATH") or ""
        return [Path(d) if Path(d).is_absolute() else self.path.parent / d for d in value.split(":") if d.strip()]

    def rewritten(self, *, display: str, recorder: Path | None, subroutine_path: tuple[Path, ...] = ()) -> str:
        """INI text with our DISPLAY and recorder HALFILE; relative file paths made absolute.

        `recorder=None` drops the INI's recording HALFILE (a machine to attach to later).
        `subroutine_path` folders come first in [RS274NGC] SUBROUTINE_PATH, before the INI's own (which
        are made absolute: LinuxCNC runs from a work folder)."""
        out: list[str] = []
        section = ""
        placed = False
        last_halfile = -1
        sub_dirs = ":".join(str(Path(d).resolve()) for d in (*subroutine_path, *self.subroutine_dirs()))
        for raw in self.text.splitlines():
            m = _SECTION.match(raw)
            if m:
                section = m.group(1).strip().upper()
                out.append(raw)
                if section == "RS274NGC" and sub_dirs:
                    out.append(f"SUBROUTINE_PATH = {sub_dirs}")
                    sub_dirs = ""
                continue
            m = _KEY.match(raw) if not raw.lstrip().startswith("#") else None
            key = m.group(1).upper() if m else ""
            value = m.group(2) if m else ""
            if section == "DISPLAY" and key == "DISPLAY":
                out.append(f"DISPLAY = {display}")
                continue
            if section == "HAL" and key == "HALFILE":
                first = value.split()[0] if value.split() else ""
                if re.match(r"record.*\.tcl$", Path(first).name):
                    placed = True
                    if recorder is not None:
                        out.append(f"HALFILE = {recorder}")
                        last_halfile = len(out) - 1
                    continue
                if first and not first.startswith("LIB:") and not Path(first).is_absolute():
                    value = value.replace(first, str(self.path.parent / first), 1)
                out.append(f"HALFILE = {value}")
                last_halfile = len(out) - 1
                continue
            if section == "RS274NGC" and key == "SUBROUTINE_PATH":
                continue  # written above, absolute
            if section == "EMCIO" and key == "TOOL_TABLE" and not Path(value).is_absolute():
                src = self.path.parent / value
                out.append(f"TOOL_TABLE = {src if src.exists() else 'feedlog.tbl'}")
                continue
            out.append(raw)
        if not placed and recorder is not None:
            if last_halfile < 0:
                raise IngestError("LinuxCNC INI has no [HAL] HALFILE to attach the recorder after",
                                  file=str(self.path))
            out.insert(last_halfile + 1, f"HALFILE = {recorder}")
        if sub_dirs:  # no [RS274NGC] section
            out += ["", "[RS274NGC]", f"SUBROUTINE_PATH = {sub_dirs}"]
        return "\n".join(out) + "\n"


@dataclass
class SessionResult:
    """What one LinuxCNC run left behind: per-sampler capture files and the driver's report."""

    workdir: Path
    sample_files: list[Path]
    layout: SamplerLayout
    report: dict
    log: str
    wall_s: float


def linuxcnc_available() -> str | None:
    """None when LinuxCNC can run here, else the reason it cannot."""
    for tool in ("linuxcnc", "halsampler", "halcmd"):
        if shutil.which(tool) is None:
            return f"LinuxCNC is not installed ({tool} not on PATH; apt-get install linuxcnc-uspace)"
    if not Path(DEBIAN_PYTHON).exists():
        return f"{DEBIAN_PYTHON} (which carries the linuxcnc module) is missing"
    return None


def _workdir(isolate: bool) -> Path:
    # an isolated session gets a private /tmp, so its files must live elsewhere to be seen from here
    base = "/var/tmp" if isolate and Path("/var/tmp").is_dir() else None
    path = Path(tempfile.mkdtemp(prefix="feedlog-linuxcnc-", dir=base))
    path.chmod(0o755)
    return path


UNSHARE = ["unshare", "--ipc", "--pid", "--mount", "--net", "--uts", "--fork", "--mount-proc"]
HOST_TMP = "/run/feedlog-host-tmp"  # where a namespace still sees the host's /tmp


def namespace_setup(*keep: str | Path) -> str:
    """Shell run first inside the namespaces: a private /tmp (lock file, NML files) and a loopback that is up.

    Paths in `keep` that lie under the host's /tmp (a checkout, a venv or a machine config there, as in
    a CI clone under /tmp) are bound back into the private /tmp, so the session still sees them.
    """
    tops = sorted({Path("/tmp", rel.parts[0]) for rel in
                   (Path(os.path.abspath(p)).relative_to("/tmp") for p in keep
                    if Path(os.path.abspath(p)).is_relative_to("/tmp")) if rel.parts})
    steps = []
    if tops:
        steps.append(f"mkdir -p {HOST_TMP} && mount --bind /tmp {HOST_TMP}")
    steps.append("mount -t tmpfs tmpfs /tmp")
    for top in tops:
        src = shlex.quote(f"{HOST_TMP}/{top.name}")
        dst = shlex.quote(str(top))
        steps.append(f"{{ [ -d {src} ] && mkdir -p {dst} || touch {dst}; }} && mount --bind {src} {dst}")
    steps.append("{ command -v ip >/dev/null && ip link set lo up || true; }")
    return " && ".join(steps)


NAMESPACE_SETUP = namespace_setup()


def isolation_available() -> str | None:
    """None when isolated sessions can run here (root, unshare allowed), else the reason."""
    if os.geteuid() != 0:
        return "isolated LinuxCNC sessions need root (unshare of mount/net/pid namespaces)"
    if shutil.which("unshare") is None:
        return "unshare (util-linux) is not installed"
    try:
        probe = subprocess.run([*UNSHARE, "sh", "-c", NAMESPACE_SETUP], capture_output=True, text=True,
                               timeout=20)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"unshare failed: {exc}"
    if probe.returncode != 0:
        return f"unshare is not permitted here: {probe.stderr.strip()[:200]}"
    return None


# scheduling of the whole LinuxCNC process tree (rtapi_app's servo thread, milltask, io, the driver,
# halsampler): inherited by every process it starts
PRIORITIES = {
    "normal": [],
    "high": ["nice", "-n", "-10"],             # a larger CFS share: ~9x a nice-0 process, ~90x a nice-10 one
    "realtime": ["chrt", "--fifo", "20"],      # SCHED_FIFO: runs before any normal process (root only)
}


def priority_prefix(priority: str) -> list[str]:
    """The command prefix that runs LinuxCNC at `priority` ('normal', 'high' or 'realtime')."""
    if priority not in PRIORITIES:
        raise ValueError(f"priority {priority!r} is not one of {', '.join(PRIORITIES)}")
    if priority != "normal" and os.geteuid() != 0:
        raise IngestError(f"priority {priority!r} needs root (raising a priority or SCHED_FIFO)")
    tool = PRIORITIES[priority][:1]
    if tool and shutil.which(tool[0]) is None:
        raise IngestError(f"priority {priority!r} needs {tool[0]} (util-linux / coreutils)")
    return list(PRIORITIES[priority])


def _launch_command(ini_path: Path, *, isolate: bool, keep: tuple[Path, ...] = (),
                    priority: str = "normal") -> list[str]:
    prefix = priority_prefix(priority)
    if not isolate:
        return [*prefix, "linuxcnc", "-r", str(ini_path)]
    return [*prefix, *UNSHARE, "sh", "-c",
            f"{namespace_setup(*keep)} && exec linuxcnc -r {shlex.quote(str(ini_path))}"]


def run_session(ini: MachineIni, program: Path, *, isolate: bool = False, timeout_s: float = 600.0,
                keep_workdir: bool = False, stop_event: threading.Event | None = None,
                priority: str = "normal", feed_override: float | None = None,
                subroutine_path: tuple[Path, ...] = (),
                feed_override_at: tuple[tuple[float, float], ...] = (),
                rapid_override_at: tuple[tuple[float, float], ...] = (),
                pause_at: tuple[tuple[float, float], ...] = ()) -> SessionResult:
    """Run `program` on the machine `ini` from homing to program end; return the capture.

    Errors of the run itself (G-code errors, aborts) are in the report: see session_error(). Call
    cleanup() once the capture files are read. keep_workdir keeps the folder also when this raises.
    Setting `stop_event` stops the program where it is (the driver sees a stop file); what was
    recorded up to then is returned as usual, with `report["stopped"]`. `priority` ('normal', 'high':
    nice -10, 'realtime': SCHED_FIFO 20; root only) schedules the whole LinuxCNC process tree above other
    work on the host, so that a program whose block rate LinuxCNC's task limits runs as on a quiet host.
    `feed_override` sets the feed override dial (1.0 = 100 %) before the program starts;
    `feed_override_at` ((seconds after the start, dial), ...) turns it while the program runs;
    `rapid_override_at` turns the rapid override dial alike;
    `pause_at` ((seconds after the start, seconds), ...) pauses the program (a feed hold) and resumes it.
    `subroutine_path`: folders where LinuxCNC finds `o<name> call` files, before the INI's SUBROUTINE_PATH
    (the program runs from a copy, so its own folder is not searched).
    """
    priority_prefix(priority)  # a bad or unavailable priority fails before anything starts
    reason = linuxcnc_available()
    if reason:
        raise IngestError(reason)
    if isolate and os.geteuid() != 0:
        raise IngestError(isolation_available() or "isolation needs root")
    layout = ini.layout()
    workdir = _workdir(isolate)
    try:
        driver = workdir / "driver.py"
        shutil.copyfile(DRIVER_SOURCE, driver)
        driver.chmod(0o755)
        recorder = workdir / "record.tcl"
        recorder.write_text(recorder_tcl(layout))
        (workdir / "feedlog.tbl").write_text("T1 P1 D6.0 ;feedlog placeholder tool\n")
        job_path = workdir / "job.json"
        sample_files = [workdir / f"sampler{c}.txt" for c in layout.channels]
        # a private /tmp hides the caller's files: the program runs from a copy in the work directory
        (workdir / "program").mkdir()
        program_copy = workdir / "program" / program.name
        try:
            shutil.copyfile(program, program_copy)
        except OSError as exc:
            raise IngestError(f"cannot read program: {exc.strerror}", file=str(program)) from None
        job = {"program": str(program_copy), "channels": layout.channels,
               "sample_files": [str(p) for p in sample_files], "result": str(workdir / "result.json"),
               "enable_signal": ENABLE_SIGNAL, "motion_time_pin": f"{MOTION_TIME_COMPONENT}.out",
               "timeout_s": timeout_s, "stop_file": str(workdir / "stop"), "feed_override": feed_override,
               "feed_override_at": [list(map(float, turn)) for turn in feed_override_at],
               "rapid_override_at": [list(map(float, turn)) for turn in rapid_override_at],
               "pause_at": [list(map(float, hold)) for hold in pause_at]}
        job_path.write_text(json.dumps(job))
        ini_path = workdir / "machine.ini"
        ini_path.write_text(ini.rewritten(display=f"{driver} {job_path}", recorder=recorder,
                                          subroutine_path=tuple(subroutine_path)))
        fifo = workdir / "rtapi_fifo"
        fifo.mkdir(mode=0o777)
        fifo.chmod(0o777)
        env = dict(os.environ, HOME=str(workdir), RTAPI_FIFO_PATH=str(fifo / "rtapi_fifo"))
        env.pop("DISPLAY", None)
        if os.geteuid() == 0:
            env["RTAPI_UID"] = str(NOBODY_UID)
        log_path = workdir / "linuxcnc.log"
        t0 = time.monotonic()
        with open(log_path, "w") as log:
            keep = (ini.path.parent, *subroutine_path, *ini.subroutine_dirs())
            command = _launch_command(ini_path, isolate=isolate, keep=keep, priority=priority)
            proc = subprocess.Popen(command, cwd=workdir, env=env,
                                    stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                    start_new_session=True)
            try:
                try:
                    wait_with_stop(proc, timeout_s + 30, stop_event, workdir / "stop")
                except KeyboardInterrupt:  # LinuxCNC runs in its own session: stop it cleanly, keep the data
                    (workdir / "stop").touch()
                    wait_with_stop(proc, 60, None, workdir / "stop")
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
        wall_s = time.monotonic() - t0
        log_text = log_path.read_text(errors="replace")
        result_path = Path(job["result"])
        if result_path.exists():
            report = json.loads(result_path.read_text())
        else:  # killed, timed out or never started: report it, and keep whatever was sampled
            tail = "\n".join(log_text.strip().splitlines()[-12:])
            report = {"ok": False, "errors": [], "phase": "unknown",
                      "abort": f"LinuxCNC did not run the driver to the end (exit {proc.returncode}); "
                               f"log tail:\n{tail}"}
    except BaseException:
        if not keep_workdir:
            shutil.rmtree(workdir, ignore_errors=True)
        raise
    # the caller reads the captures (also of an aborted run: recorded data is kept) and then cleans up
    return SessionResult(workdir=workdir, sample_files=sample_files, layout=layout, report=report,
                         log=log_text, wall_s=wall_s)


def wait_with_stop(proc: subprocess.Popen, timeout_s: float, stop_event: threading.Event | None,
                   stop_file: Path) -> None:
    """Wait for `proc`; when `stop_event` is set, ask the driver to stop by creating `stop_file`."""
    end = time.monotonic() + timeout_s
    while True:
        try:
            proc.wait(timeout=0.2)
            return
        except subprocess.TimeoutExpired:
            if time.monotonic() > end:
                raise
        if stop_event is not None and stop_event.is_set() and not stop_file.exists():
            stop_file.touch()


def cleanup(result: SessionResult) -> None:
    shutil.rmtree(result.workdir, ignore_errors=True)


def session_error(report: dict, program: Path, *, sampled: bool = True) -> FeedlogError | None:
    """What went wrong in a session, as our error; None when it ran to the end.

    A stop on request is not a failure (a shorter recording) unless it came before anything was
    sampled (`sampled` False): then there is nothing to write, and the error says so.
    """
    if report.get("errors"):
        return program_error(report, program)
    if report.get("stopped"):
        if not sampled:
            return IngestError("stopped before the machine started recording; nothing was written",
                               file=str(program))
        return None
    if report.get("abort") or not report.get("ok"):
        return IngestError(f"LinuxCNC session aborted in phase {report.get('phase')}: "
                           f"{report.get('abort', 'unknown reason')}", file=str(program))
    return None


def program_error(report: dict, program: Path) -> ProgramError:
    """LinuxCNC's own G-code errors become a ProgramError naming the file and line."""
    errors = report["errors"]
    first = errors[0]
    text = " ".join(str(first.get("text", "")).split())
    m = _LINE_IN_TEXT.search(text)
    # LinuxCNC names the line in some messages; otherwise the interpreter's read position tells it
    line = int(m.group(1)) if m else (first.get("read_line") or first.get("motion_line")
                                      or first.get("current_line") or None)
    if line is None:
        line = locate_error_line(program, text)
    more = f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""
    return ProgramError(f"LinuxCNC: {text}{more}", file=str(program), line=line)


def locate_error_line(program: Path, message: str) -> int | None:
    """The program line an interpreter error belongs to, when LinuxCNC's message does not say.

    LinuxCNC's stand-alone interpreter (`rs274 -g`) prints the message followed by the offending
    block; that block is looked up in the program text.
    """
    if shutil.which("rs274") is None or not message:
        return None
    try:
        out = subprocess.run(["rs274", "-g", str(program)], capture_output=True, text=True, timeout=30,
                             stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired):
        return None
    printed = (out.stdout + "\n" + out.stderr).splitlines()
    wanted = " ".join(message.split())
    for i, text in enumerate(printed[:-1]):
        if " ".join(text.split()) == wanted:
            block = printed[i + 1].strip().lower()
            for number, source in enumerate(program.read_text(errors="replace").splitlines(), start=1):
                if block and source.strip().lower() == block:
                    return number
    return None


__all__ = ["MachineIni", "SessionResult", "cleanup", "isolation_available", "linuxcnc_available", "program_error", "run_session",
           "session_error"]
