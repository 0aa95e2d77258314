"""The `linuxcnc` recording source: run a part program on LinuxCNC and record every servo period.

`feedlog record --source linuxcnc --ini MACHINE.ini PROGRAM.ngc -o recordings/NAME.mcap` starts
LinuxCNC headless with feedlog's driver and recorder HAL (linuxcnc_session), homes, runs the program
and writes a feedlog recording (streams axes, joints, feed, line, status at the servo rate) with the
program, the INI and the matching machine profile attached. `record_linuxcnc()` is the same as a
function. Attaching to an already running LinuxCNC is described in docs/linuxcnc.md.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import shutil
import threading
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import pandas as pd

from feedlog.errors import FeedlogError, IngestError
from feedlog.ingest.linuxcnc_capture import has_samples, load_capture, motion_span
from feedlog.ingest.linuxcnc_session import MachineIni, cleanup, run_session, session_error
from feedlog.ingest.subroutine_files import subroutine_attachments
from feedlog.recording import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT, Recording
from feedlog.ingest.writer import write_recording
from feedlog.profile import load_profile

INI_ATTACHMENT = "machine.ini"
# which streams (and columns) a session keeps: "full" = everything the recorder samples; "compact" =
# what align, train and viz use (positions, program line, LinuxCNC's path speed) for training sessions
STREAM_SETS: dict[str, dict[str, list[str] | None] | None] = {
    "full": None,
    "compact": {"axes": None, "line": None, "feed": ["t_ns", "feed_mm_min"]},
}
COMPACT_ZSTD_LEVEL = 19  # compact sessions are written once and read many times: spend the time
CONTROLLER = "LinuxCNC"
# INI [KINS] KINEMATICS module -> shipped machine profile
PROFILE_BY_KINEMATICS = {"trivkins": "linuxcnc-xyz", "xyzac-trt-kins": "linuxcnc-xyzac"}


def profile_for_ini(ini: MachineIni) -> str:
    """The shipped profile that matches the INI's kinematics (`--profile` overrides it)."""
    kins = (ini.get("KINS", "KINEMATICS") or "").split()
    module = kins[0] if kins else ""
    name = PROFILE_BY_KINEMATICS.get(module)
    if name is None:
        raise IngestError(f"no shipped machine profile for kinematics {module!r}; pass --profile "
                          f"(known: {', '.join(f'{k} -> {v}' for k, v in PROFILE_BY_KINEMATICS.items())})",
                          file=str(ini.path))
    return name


def profile_toml_for(profile: str | None, ini: MachineIni) -> tuple[str, bytes]:
    """The profile's name and TOML text: `profile` (name or path) or the one matching the INI."""
    spec = profile or profile_for_ini(ini)
    loaded = load_profile(spec)
    path = Path(spec)
    if path.suffix == ".toml" and path.is_file():
        return loaded.name, path.read_bytes()
    return loaded.name, resources.files("feedlog.profiles").joinpath(f"{spec}.toml").read_bytes()


def record_linuxcnc(ini: str | Path, program: str | Path, out: str | Path, *, profile: str | None = None,
                    isolate: bool = False, timeout_s: float = 600.0, overwrite: bool = False,
                    compression: str = "zstd", notes: str = "", streams: str = "full",
                    priority: str = "normal", level: int | None = None,
                    stop_event: threading.Event | None = None, feed_override: float | None = None,
                    subroutine_path: tuple[str | Path, ...] = (),
                    feed_override_at: tuple[tuple[float, float], ...] = (),
                    pause_at: tuple[tuple[float, float], ...] = (),
                    rapid_override_at: tuple[tuple[float, float], ...] = ()) -> dict[str, Any]:
    """Run `program` on the LinuxCNC machine `ini`, write the recording to `out`, return a summary.

    Setting `stop_event` (the CLI does on SIGINT/SIGTERM) stops the machine where it is and writes
    what was recorded (metadata `status = stopped`).

    `streams`: "full" (axes, joints, feed, line, status) or "compact" (axes, line and feed_mm_min only,
    zstd level 19 unless `level` says otherwise: about half the size). `priority`: "normal", "high" or
    "realtime" (root): how LinuxCNC's processes are scheduled against other work on the host.
    `feed_override` (0 < x <= the INI's MAX_FEED_OVERRIDE) turns the feed override dial before the program
    starts; the recording's metadata says so (`feed_override`). `feed_override_at` ((seconds after the start,
    dial), ...) turns the dial while the program runs (metadata `feed_override_turns`: seconds of motion
    time after the start, and dial); `rapid_override_at` turns the rapid override dial alike (0 < dial <= 1;
    metadata `rapid_override_turns`). `pause_at` ((seconds after the start, seconds), ...) pauses the program
    and resumes it, an operator's feed hold (metadata `feed_holds`: seconds of motion time after the start
    when paused and when resumed). `subroutine_path`: folders where LinuxCNC
    finds `o<name> call` files, before the INI's SUBROUTINE_PATH; the files the program calls are
    attached as `subroutines/<name>.ngc` (feedlog.ingest.subroutine_files).

    A G-code error raises ProgramError (file, line, LinuxCNC's message); if the machine had already
    moved, what was recorded up to then is still written to `out` (metadata `status = aborted`).
    """
    if streams not in STREAM_SETS:
        raise ValueError(f"streams {streams!r} is not one of {', '.join(STREAM_SETS)}")
    if level is None and streams == "compact" and compression == "zstd":
        level = COMPACT_ZSTD_LEVEL
    ini_cfg = MachineIni.read(ini)
    program = Path(program)
    out = Path(out)
    if not program.is_file():
        raise IngestError("program not found", file=str(program))
    if out.exists() and not overwrite:
        raise IngestError("output exists; pass --overwrite to replace it", file=str(out))
    for dial in [feed_override, *(turn[1] for turn in feed_override_at)]:
        if dial is not None and not (0.0 < dial <= 10.0):
            raise IngestError(f"feed override must be within (0, 10], got {dial}")
    for _, dial in rapid_override_at:
        if not 0.0 < dial <= 1.0:
            raise IngestError(f"rapid override must be within (0, 1], got {dial}")
    profile_name, profile_toml = profile_toml_for(profile, ini_cfg)
    subroutine_path = tuple(Path(d) for d in subroutine_path)
    for folder in subroutine_path:
        if not folder.is_dir():
            raise IngestError("subroutine folder not found", file=str(folder))
    subroutines = subroutine_attachments(program.read_bytes(), [*subroutine_path, *ini_cfg.subroutine_dirs()])
    session = run_session(ini_cfg, program, isolate=isolate, timeout_s=timeout_s, stop_event=stop_event,
                          priority=priority, feed_override=feed_override, subroutine_path=subroutine_path,
                          feed_override_at=tuple(feed_override_at), rapid_override_at=tuple(rapid_override_at),
                          pause_at=tuple(pause_at))
    sampled = has_samples(session.sample_files)
    error = session_error(session.report, program, sampled=sampled)
    if error is not None and not sampled:
        cleanup(session)
        raise error  # failed or stopped before anything was sampled
    with keep_captures_on_failure(session.workdir):
        captured, missing = load_capture(session.sample_files, session.layout, period_ns=ini_cfg.servo_period_ns,
                                        linear_units=ini_cfg.linear_units, source=str(program))
        summary = write_session(captured, missing, session.report, ini=ini_cfg, program=program.name,
                                program_bytes=program.read_bytes(), profile_name=profile_name,
                                profile_toml=profile_toml, out=out, overwrite=overwrite, compression=compression,
                                notes=notes, error=error, wall_s=session.wall_s, stream_set=streams, level=level,
                                priority=priority, extra_attachments=subroutines)
    cleanup(session)
    return finish(summary, error, out)


@contextlib.contextmanager
def keep_captures_on_failure(workdir: Path) -> Iterator[None]:
    """If converting or writing fails, the raw sampler captures stay on disk and the error says where."""
    try:
        yield
    except FeedlogError as exc:
        raise IngestError(f"{exc} (raw sampler captures kept in {workdir})") from exc


def finish(summary: dict[str, Any] | None, error: FeedlogError | None, out: Path) -> dict[str, Any]:
    """The summary of a session that ended normally; else its error (noting a recording kept)."""
    if error is None:
        assert summary is not None
        return summary
    if summary is not None:
        error.message = f"{error.message} (recording up to the error kept in {out})"
        error.args = (error._render(),)
    raise error


def select_streams(streams: dict[str, pd.DataFrame], stream_set: str) -> dict[str, pd.DataFrame]:
    """The streams and columns that `stream_set` (a STREAM_SETS name) keeps; all for "full"."""
    if stream_set not in STREAM_SETS:
        raise ValueError(f"streams {stream_set!r} is not one of {', '.join(STREAM_SETS)}")
    chosen = STREAM_SETS[stream_set]
    if chosen is None:
        return dict(streams)
    return {name: (streams[name] if columns is None else streams[name][columns])
            for name, columns in chosen.items() if name in streams}


def write_session(streams: dict[str, pd.DataFrame], missing: int, report: dict, *, ini: MachineIni,
                  program: str, program_bytes: bytes | None, profile_name: str, profile_toml: bytes,
                  out: Path, overwrite: bool, compression: str = "zstd", notes: str = "",
                  error: FeedlogError | None = None, wall_s: float = 0.0, stream_set: str = "full",
                  level: int | None = None, priority: str = "normal",
                  extra_attachments: dict[str, bytes] | None = None) -> dict[str, Any] | None:
    """Write one recorded LinuxCNC session (also a cut-short one) and return its summary.

    `stream_set` names an entry of STREAM_SETS: the streams (and columns) written; cycle time and motion
    span are measured on the full capture first.

    `error` (how the session failed, if it did) goes into the `status` metadata. A failed session in
    which nothing moved writes nothing and returns None.
    """
    period_ns = ini.servo_period_ns
    span = motion_span(streams["axes"], period_ns)
    if error is not None and span is None:
        return None  # nothing moved: no recording to keep
    motion_time_s = float(report.get("motion_time_end_s", float("nan"))) - float(report.get("motion_time_start_s", 0.0))
    axes_t = streams["axes"]["t_ns"]
    metadata = {
        "machine": profile_name,
        "controller": f"{CONTROLLER} {report.get('linuxcnc_version', '')}".strip(),
        "units": "mm, deg, s",
        "nominal_rate_hz": f"{1e9 / period_ns:g}",
        "start_time": dt.datetime.fromtimestamp(float(report.get("run_wall_start", 0.0)),
                                                tz=dt.UTC).isoformat(timespec="milliseconds"),
        "notes": notes,
        "source": "linuxcnc",
        "program": program,
        "ini": ini.path.name,
        "servo_period_ns": str(period_ns),
        "cycle_time_s": f"{span.cycle_time_s:.6f}" if span else "",
        "motion_start_ns": str(int(axes_t.iloc[span.first])) if span else "",
        "motion_end_ns": str(int(axes_t.iloc[span.last])) if span else "",
        "linuxcnc_motion_time_s": f"{motion_time_s:.6f}",
        "sampler_overruns": str(int(report.get("overruns", 0))),
        "streams": stream_set,
        "status": (f"aborted: {error}" if error is not None else
                   "stopped" if report.get("stopped") else "complete"),
    }
    if priority != "normal":
        metadata["priority"] = priority
    if report.get("feed_override") is not None:
        metadata["feed_override"] = f"{float(report['feed_override']):g}"
    for key in ("feed_override_turns", "rapid_override_turns"):  # a dial turned mid-program: "s after the start:dial"
        if report.get(key):
            start = float(report.get("motion_time_start_s", 0.0))
            metadata[key] = " ".join(f"{t['motion_time_s'] - start:.3f}:{t['scale']:g}" for t in report[key])
    if report.get("feed_holds"):  # paused mid-program: "s after the start:s when resumed" each
        start = float(report.get("motion_time_start_s", 0.0))
        metadata["feed_holds"] = " ".join(f"{h['motion_time_s'] - start:.3f}:{h['resumed_motion_time_s'] - start:.3f}"
                                          for h in report["feed_holds"] if "resumed_motion_time_s" in h)
    attachments = {INI_ATTACHMENT: ini.text.encode(), PROFILE_ATTACHMENT: profile_toml}
    for hal_file in ini.hal_files():  # e.g. trt.hal with the trunnion kinematics' offsets
        attachments.setdefault(f"hal/{hal_file.name}", hal_file.read_bytes())
    if program_bytes is not None:
        attachments[PROGRAM_ATTACHMENT] = program_bytes
    attachments.update(extra_attachments or {})  # e.g. the subroutine files the program calls
    kept = select_streams(streams, stream_set)
    recording = Recording(streams=kept, metadata=metadata, attachments=attachments,
                          dropped_frames=missing + int(report.get("overruns", 0)), source=str(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    write_recording(out, recording, overwrite=overwrite, compression=compression, level=level)
    return {
        "out": str(out),
        "program": program,
        "machine": profile_name,
        "samples": int(len(streams["axes"])),
        "dropped_frames": recording.dropped_frames,
        "cycle_time_s": span.cycle_time_s if span else 0.0,
        "linuxcnc_motion_time_s": motion_time_s,
        "duration_s": recording.duration_s,
        "wall_s": round(wall_s, 3),
        "status": metadata["status"],
    }


# ---- source registry interface (feedlog.ingest.cli_record) ---------------------------------------

def dial_turn(text: str, *, max_scale: float = 10.0) -> tuple[float, float]:
    """`S:SCALE` (seconds after the start, dial) of --feed-override-at (0 < SCALE <= `max_scale`)."""
    try:
        at, scale = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected S:SCALE (seconds:dial, e.g. 3.5:0.7), got {text!r}") from None
    if not (0 <= at < float("inf") and 0 < scale <= max_scale):
        raise argparse.ArgumentTypeError(f"need S >= 0 and 0 < SCALE <= {max_scale:g}, got {text!r}")
    return at, scale


def feed_hold(text: str) -> tuple[float, float]:
    """`S:D` (seconds after the start, seconds paused) of --pause-at."""
    try:
        at, duration = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected S:D (seconds:seconds, e.g. 3:4), got {text!r}") from None
    if not (0 <= at < float("inf") and 0 < duration < float("inf")):
        raise argparse.ArgumentTypeError(f"need S >= 0 and D > 0, got {text!r}")
    return at, duration
def rapid_dial_turn(text: str) -> tuple[float, float]:
    """`S:SCALE` of --rapid-override-at: LinuxCNC's rapid dial goes to 100 % at most."""
    return dial_turn(text, max_scale=1.0)


def add_arguments(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--ini", type=Path, help="LinuxCNC machine INI (e.g. configs/xyz.ini)")
    group.add_argument("--isolate", action="store_true",
                       help="run LinuxCNC in private namespaces (root only; allows parallel sessions)")
    group.add_argument("--attach", action="store_true",
                       help="record a LinuxCNC that is already running (see docs/linuxcnc.md)")
    group.add_argument("--until-stopped", action="store_true",
                       help="with --attach: record until Ctrl-C/SIGTERM, not just until the program ends")
    group.add_argument("--timeout-s", type=float, default=600.0, help="give up after this long (default 600)")
    group.add_argument("--streams", choices=tuple(STREAM_SETS), default="full",
                       help="full: axes, joints, feed, line, status; compact: axes, line and feed_mm_min, "
                            "zstd level 19 (about half the size; for training sessions)")
    group.add_argument("--feed-override", type=float, metavar="SCALE",
                       help="turn the feed override dial to SCALE (1.0 = 100 %%) before the program starts")
    group.add_argument("--feed-override-at", action="append", default=[], type=dial_turn, metavar="S:SCALE",
                       help="turn the feed override dial to SCALE S seconds after the program starts (repeatable)")
    group.add_argument("--pause-at", action="append", default=[], type=feed_hold, metavar="S:D",
                       help="pause the program S seconds after it starts and resume it D seconds later (a feed "
                            "hold; repeatable)")
    group.add_argument("--rapid-override-at", action="append", default=[], type=rapid_dial_turn, metavar="S:SCALE",
                       help="turn the rapid override dial to SCALE (at most 1.0) S seconds after the program "
                            "starts (repeatable)")
    group.add_argument("--subroutine-path", action="append", default=[], type=Path, metavar="DIR",
                       help="folder where LinuxCNC finds o<name> call files (before the INI's SUBROUTINE_PATH; "
                            "repeatable); the files called are attached to the recording")
    group.add_argument("--priority", choices=("normal", "high", "realtime"), default="normal",
                       help="schedule LinuxCNC's processes above other work (root): high = nice -10, "
                            "realtime = SCHED_FIFO 20")


def record(args: argparse.Namespace) -> dict[str, Any]:
    if getattr(args, "attach", False):
        from feedlog.ingest.linuxcnc_attach import attach_linuxcnc
        if args.ini is None:
            raise FeedlogError("--attach needs --ini: the INI the running LinuxCNC was started with")
        return attach_linuxcnc(args.ini, args.out, program=getattr(args, "program", None),
                               profile=getattr(args, "profile", None), timeout_s=args.timeout_s,
                               overwrite=getattr(args, "overwrite", False),
                               until_program_end=not args.until_stopped,
                               stop_event=getattr(args, "stop_event", None))
    if args.ini is None:
        raise FeedlogError("--source linuxcnc needs --ini MACHINE.ini")
    if getattr(args, "program", None) is None:
        raise FeedlogError("--source linuxcnc needs a PROGRAM.ngc to run")
    if shutil.which("linuxcnc") is None:
        raise FeedlogError("LinuxCNC is not installed here (apt-get install linuxcnc-uspace)")
    return record_linuxcnc(args.ini, args.program, args.out, profile=getattr(args, "profile", None),
                           isolate=args.isolate, timeout_s=args.timeout_s,
                           overwrite=getattr(args, "overwrite", False),
                           streams=getattr(args, "streams", "full"), priority=getattr(args, "priority", "normal"),
                           stop_event=getattr(args, "stop_event", None),
                           feed_override=getattr(args, "feed_override", None),
                           subroutine_path=tuple(getattr(args, "subroutine_path", None) or ()),
                           feed_override_at=tuple(sorted(getattr(args, "feed_override_at", None) or ())),
                           rapid_override_at=tuple(sorted(getattr(args, "rapid_override_at", None) or ())),
                           pause_at=tuple(sorted(getattr(args, "pause_at", None) or ())))
