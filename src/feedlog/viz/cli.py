"""`feedlog view RECORDING [--program P] [--sim] [--model M] [-o/--save out.rrd | --connect | --serve] [--json]`.

Builds the Rerun overlays of one recording (programmed vs measured path, measured / commanded /
simulated / learned feeds, residuals, block times) with a blueprint made in code, and sends them to
a file, a running viewer, a served web viewer, or a freshly spawned viewer (the default).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.cli_options import add_overwrite, add_quiet
from feedlog.errors import FeedlogError
from feedlog.rerun_stream import new_stream
from feedlog.storage import writable_dir
from feedlog.viz.overlay import log_view, view_blueprint
from feedlog.viz.plots import plot_view
from feedlog.viz.predictions import model_prediction
from feedlog.viz.prepare import prepare_view
from feedlog.viz.sources import gather
from feedlog.viz.stages import stage_function


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", type=Path, help="feedlog recording (.mcap)")
    parser.add_argument("--program", type=Path, help="part program (default: the one attached to the recording)")
    parser.add_argument("--profile", help="machine profile name or TOML (default: the attached one)")
    parser.add_argument("--sim", action="store_true", help="overlay the simulated feed (needs a profile)")
    parser.add_argument("--model", type=Path, action="append", default=[],
                        help="trained model checkpoint (.pt) whose prediction to overlay; repeatable")
    parser.add_argument("--lenient", action="store_true",
                        help="skip G-codes the parser does not support (each one is listed) instead of failing")
    parser.add_argument("--no-align", action="store_true",
                        help="take block times from the recording's line stream instead of aligning")
    parser.add_argument("--arrow-every", type=int, default=50, help="five-axis: one orientation arrow per N samples")
    parser.add_argument("--png", type=Path, metavar="DIR", help="also write the overlays as PNG plots into DIR")
    sink = parser.add_mutually_exclusive_group()
    sink.add_argument("-o", "--out", "--save", dest="save", type=Path, metavar="OUT.rrd",
                      help="write a .rrd file instead of showing")
    sink.add_argument("--connect", nargs="?", const="", metavar="URL",
                      help="send to a running Rerun viewer (default URL when none given)")
    sink.add_argument("--serve", action="store_true", help="serve a web viewer and keep running until Ctrl-C")
    add_overwrite(parser, help="replace an existing --save file")
    add_quiet(parser, help="print nothing but errors")
    parser.add_argument("--json", action="store_true",
                        help="print what was sent (samples per series, the saved file, plots, notes) as JSON")


WEB_PORT = 9090


def check_display() -> None:
    """A spawned viewer needs a display: say so before any work is done."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise FeedlogError("no display to open a Rerun viewer on (DISPLAY/WAYLAND_DISPLAY unset); "
                           "use --save OUT.rrd (then `rerun OUT.rrd` elsewhere), --connect URL or --serve")


def spawn_viewer(stream, blueprint) -> None:
    """Start a Rerun viewer (the `rerun` next to this Python first) or say how else to look."""
    bin_dir = Path(sys.executable).parent
    if (bin_dir / "rerun").exists() and str(bin_dir) not in os.environ.get("PATH", "").split(os.pathsep):
        os.environ["PATH"] = f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}"
    try:
        stream.spawn(default_blueprint=blueprint)
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[0]
        raise FeedlogError(f"cannot start the Rerun viewer ({first}); use --save OUT.rrd, --connect or --serve") \
            from None


def run(args: argparse.Namespace) -> int:
    if args.save is not None and args.save.exists() and not args.overwrite:
        raise FeedlogError(f"{args.save} exists; pass --overwrite to replace it")
    if args.save is None and args.connect is None and not args.serve:
        check_display()
    if args.save is not None:
        writable_dir(args.save.parent)  # a read-only or missing place: said before any work
    recording = stage_function("read_recording")(args.recording)
    name = args.recording.stem
    gathered = gather(recording, name=name, program=args.program, profile=args.profile, simulate=args.sim,
                      align=not args.no_align, arrow_every=args.arrow_every, lenient=args.lenient)
    for checkpoint in args.model:
        if gathered.program is None:
            raise FeedlogError(f"--model {checkpoint}: a model predicts from the part program, and there is none")
        gathered.inputs.models.append(model_prediction(checkpoint, gathered.program, profile=gathered.profile))
    if args.sim and gathered.sim is None:
        gathered.notes.append("--sim given but no simulation could run (see above)")
    data = prepare_view(gathered.inputs)
    notes = gathered.notes + data.notes
    if not (args.quiet or args.json):
        for note in notes:
            print(f"note: {note}")

    if args.save is None:
        counts = _send(args, data, name, None)
    else:  # written under a temporary name, renamed when Rerun has written all of it
        with atomic_output(args.save) as temporary:
            counts = _send(args, data, name, temporary)
    plots = plot_view(data, args.png) if args.png is not None else {}
    if args.json:
        print(json.dumps({"recording": str(args.recording), "samples": sum(counts.values()), "series": counts,
                          "saved": None if args.save is None else str(args.save),
                          "plots": {kind: str(path) for kind, path in plots.items()}, "notes": notes}, indent=1))
    elif not args.quiet:
        print(f"{name}: {sum(counts.values())} samples over {len(counts)} series")
        for kind, path in plots.items():
            print(f"{kind} plot: {path}")
        if args.save is not None:
            print(f"saved {args.save}; open it with: rerun {args.save}")
    if args.serve:
        try:
            while True:
                time.sleep(1)
        except KeyboardInterrupt:
            pass
    return 0


def _send(args: argparse.Namespace, data, name: str, save: Path | None) -> dict[str, int]:
    """Log the view to its sink: the file `save` (complete when this returns), a viewer or a web server;
    returns the samples logged per series."""
    stream = new_stream(name)
    blueprint = view_blueprint(data)
    binary = None
    if save is not None:  # feedlog writes the bytes: a write that fails is an error, not a Rerun hang
        binary = stream.binary_stream()
        stream.send_blueprint(blueprint, make_active=False, make_default=True)
    elif args.connect is not None:
        stream.connect_grpc(args.connect or None, default_blueprint=blueprint)
    elif args.serve:
        uri = stream.serve_grpc(default_blueprint=blueprint)
        import rerun as rr
        rr.serve_web_viewer(web_port=WEB_PORT, open_browser=False, connect_to=uri)
        print(f"serving {uri}; web viewer: http://localhost:{WEB_PORT}/?url={uri} "
              f"(or `rerun --connect {uri}`); Ctrl-C to stop")
    else:
        spawn_viewer(stream, blueprint)
    stream.send_recording_name(name)
    counts = log_view(data, stream)
    if binary is not None:
        save.write_bytes(binary.read() or b"")
        return counts
    try:
        stream.flush()
    except RuntimeError as exc:  # the viewer went away or was never reachable
        raise FeedlogError(f"could not deliver the recording to the Rerun viewer: {exc}") from None
    return counts
