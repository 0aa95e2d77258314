"""`feedlog record --source NAME [PROGRAM] [--profile P] -o REC.mcap`: record a live session.

Sources are modules registered below by name; each provides `add_arguments(group)` for its own
options and `record(args) -> dict` (a summary). A source that sets `STOPS_ON_EVENT = True` gets
`args.stop_event`: SIGINT and SIGTERM set it and the source finishes its file and returns. Other
sources keep Python's default signal handling. A summary with an `error` (a write that failed) exits
with code 1: the recording holds everything flushed before.
"""

from __future__ import annotations

import argparse
import json
import signal
import threading
from pathlib import Path
from types import ModuleType

from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.errors import FeedlogError, IngestError, OutputError
from feedlog.recording import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT
from feedlog.registry import Registry

# source name -> module with add_arguments(group) and record(args) -> dict
SOURCES: Registry[ModuleType] = Registry.lazy("record source", {
    "can": "feedlog.ingest.source_can",
    "sim": "feedlog.ingest.source_sim",
    "linuxcnc": "feedlog.ingest.linuxcnc",
    "mtconnect": "feedlog.ingest.source_mtconnect",
    "opcua": "feedlog.ingest.source_opcua",
})


def _source_module(name: str) -> ModuleType | None:
    """The source's module, or None when it is not in this installation."""
    return SOURCES.get_optional(name)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("program", nargs="?", help="part program (attached to the recording; sim and linuxcnc run it)")
    parser.add_argument("--source", required=True, choices=list(SOURCES),
                        help="where the data comes from: a CAN bus (can), feedlog's own simulation (sim) or a "
                             "LinuxCNC machine (linuxcnc), an MTConnect agent (mtconnect) or an OPC UA server (opcua)")
    parser.add_argument("--profile", help="machine profile (name or TOML path), attached to the recording")
    add_output(parser, required=True, metavar="REC.mcap", help="recording to write (.mcap)")
    add_overwrite(parser, help="replace an existing output file")
    capture = parser.add_argument_group("CAN capture (can, sim)")
    capture.add_argument("--dbc", help="DBC describing the frames (default: feedlog_axes.dbc)")
    capture.add_argument("--duration-s", type=float, help="stop after this many seconds")
    add_quiet(capture, help="no live progress line")
    capture.add_argument("--json", action="store_true", help="print the summary as JSON")
    network = parser.add_argument_group("network sources (mtconnect, opcua)")
    network.add_argument("--url", help="the agent or server: http://AGENT:5000, opc.tcp://HOST:4840")
    network.add_argument("--interval-ms", type=int, default=100, help="sampling interval in ms (default 100)")
    for name in SOURCES:
        module = _source_module(name)
        if module is not None:
            module.add_arguments(parser.add_argument_group(f"--source {name}"))


def session_attachments(args: argparse.Namespace) -> tuple[dict[str, str], dict[str, bytes]]:
    """Session metadata and attachments from the common arguments (program, profile)."""
    metadata: dict[str, str] = {"machine": "", "controller": "", "units": "mm, deg, mm/min", "notes": ""}
    attachments: dict[str, bytes] = {}
    if getattr(args, "program", None):
        path = Path(args.program)
        if not path.is_file():
            raise IngestError("part program not found", file=str(path))
        attachments[PROGRAM_ATTACHMENT] = path.read_bytes()
        metadata["program"] = path.name
    if getattr(args, "profile", None):
        from feedlog.profile import load_profile

        profile = load_profile(args.profile)
        attachments[PROFILE_ATTACHMENT] = profile.to_toml().encode("utf-8")
        metadata["machine"] = profile.name
    return metadata, attachments


def run(args: argparse.Namespace) -> int:
    module = _source_module(args.source)
    if module is None:
        raise FeedlogError(f"record source {args.source!r} is not available in this version")
    if Path(args.out).exists() and not args.overwrite:
        raise IngestError("output exists; pass --overwrite to replace it", file=args.out)
    args.stop_event = threading.Event()
    previous = {}

    def on_signal(signum, frame) -> None:
        args.stop_event.set()

    if getattr(module, "STOPS_ON_EVENT", False):
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, on_signal)
    try:
        summary = module.record(args)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if args.json:
        print(json.dumps(summary, indent=2, default=str))
    else:
        print(", ".join(f"{k}: {v}" for k, v in summary.items() if k != "streams"))
    if summary.get("error"):
        raise OutputError(f"recording stopped: {summary['error']}; the samples flushed before are kept "
                          f"in {args.out}")
    return 0
