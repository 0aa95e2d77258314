"""`feedlog import SOURCE [--preset NAME | --map ...] [--program P.ngc] [--profile M] -o REC.mcap`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.errors import IngestError
from feedlog.ingest.mapping import preset_description, preset_names
from feedlog.ingest.readers import SUFFIXES, ImportOptions, read_source
from feedlog.recording import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT
from feedlog.ingest.summary import format_summary, summarize
from feedlog.ingest.data_checks import run_checks
from feedlog.ingest.writer import write_recording


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", nargs="?",
                        help=f"file to convert ({', '.join(SUFFIXES)}); prefix can: for a python-can CSV log")
    add_output(parser, metavar="REC.mcap", help="recording to write (.mcap)")
    add_overwrite(parser, help="replace an existing output file")
    parser.add_argument("--compression", choices=["none", "lz4", "zstd"], default="none",
                        help="MCAP chunk compression (default none: fastest, float positions barely "
                             "compress; zstd for small archives)")
    mapping = parser.add_mutually_exclusive_group()
    mapping.add_argument("--preset", help="named column mapping (see --list-presets)")
    mapping.add_argument("--map", dest="mapping", metavar="T=COL,...",
                         help="column mapping, e.g. t=time,x=X1_ActualPosition,feed=PathVelocity "
                              "(generic MCAP: x=/topic:field.path)")
    parser.add_argument("--list-presets", action="store_true", help="list the column-mapping presets and exit")
    units = parser.add_argument_group("declared units (override the preset)")
    units.add_argument("--time-unit", choices=["s", "ms", "us", "ns", "datetime"])
    units.add_argument("--length-unit", help="mm, in, um, m")
    units.add_argument("--angle-unit", help="deg or rad")
    units.add_argument("--feed-unit", help="e.g. mm/min, mm/s, in/min")
    units.add_argument("--timezone", help="zone of wall-clock times without an offset (default UTC)")
    units.add_argument("--time-format", help="strftime format of wall-clock times (default ISO 8601)")
    parser.add_argument("--delimiter", default=None, help="CSV field delimiter (default: the preset's, else ,)")
    parser.add_argument("--rate-hz", type=float, default=None, metavar="HZ",
                        help="a CSV without a time column, written at a fixed rate: t = row index / HZ")
    parser.add_argument("--dbc", help="DBC file for CAN logs (default: feedlog's own feedlog_axes.dbc)")
    parser.add_argument("--device", help="MTConnect: the device to read when the file holds several")
    parser.add_argument("--lenient", action="store_true", help="skip and count bad rows instead of failing")
    parser.add_argument("--recover", action="store_true", help="keep what a cut-off feedlog recording holds")
    parser.add_argument("--program", help="part program to attach (program.ngc)")
    parser.add_argument("--profile", help="machine profile to attach (name or TOML path)")
    parser.add_argument("--machine", help="machine name for the session metadata")
    parser.add_argument("--notes", help="free text for the session metadata")
    add_quiet(parser, help="print only warnings, not the recording's summary")
    parser.add_argument("--json", action="store_true", help="print the summary and the warnings as JSON")


def run(args: argparse.Namespace) -> int:
    if args.list_presets:
        for name in preset_names():
            print(f"{name:<20} {preset_description(name)}")
        return 0
    if not args.source or not args.out:
        raise IngestError("feedlog import needs SOURCE and -o REC.mcap")
    options = ImportOptions(preset=args.preset, mapping=args.mapping, time_unit=args.time_unit,
                            length_unit=args.length_unit, angle_unit=args.angle_unit, feed_unit=args.feed_unit,
                            timezone=args.timezone, time_format=args.time_format, delimiter=args.delimiter,
                            rate_hz=args.rate_hz, device=args.device,
                            dbc=args.dbc, strict=not args.lenient, recover=args.recover)
    recording = read_source(args.source, options)
    attach_session(recording, program=args.program, profile=args.profile, machine=args.machine, notes=args.notes)
    recording.metadata.update(run_checks(recording))
    write_recording(args.out, recording, overwrite=args.overwrite, compression=args.compression)
    recording.source = args.out
    warnings = {key: recording.metadata[key] for key in WARNINGS if key in recording.metadata}
    if args.json:  # one document: the summary `feedlog info --json` gives, and the warnings
        print(json.dumps({**summarize(recording), "warnings": warnings}, indent=2, default=str))
        return 0
    if not args.quiet:
        print(format_summary(summarize(recording)))
        print(mapping_line(recording))
    for key, text in warnings.items():
        print(f"warning: {key}: {text}")
    return 0


# metadata an import sets when it skipped or could not check something: printed as warnings
WARNINGS = ("bad_rows", "bad_records", "bad_frames", "unknown_ids", "short_frames", "incomplete_samples",
            "recovered", "unavailable", "unit_check", "unit_check_requested_feed", "position_jumps",
            "quantised", "program_lines")


def mapping_line(recording) -> str:
    """`mapped: feed=Feed_Rate, line=Block_Number (preset mtconnect-shdr); ...`: what the import took from
    where, and what a recording without positions can and cannot be used for."""
    meta = recording.metadata
    found = meta.get("mapping_found") or meta.get("columns", "")
    text = f"mapped: {', '.join(p for p in found.split(',') if p and not p.startswith('t=')) or 'nothing'}"
    if meta.get("mapping"):
        text += f" ({meta['mapping']})"
    if meta.get("mapping_names"):
        text += f", by name {meta['mapping_names'].replace(',', ', ')}"
    if "axes" not in recording.streams:
        text += ("; no positions: align works on the line stream alone"
                 if "line" in recording.streams else "; no positions and no program line")
    return text


def attach_session(recording, *, program: str | None = None, profile: str | None = None,
                   machine: str | None = None, notes: str | None = None) -> None:
    """Attach the part program and machine profile and fill the session metadata keys."""
    from feedlog.profile import load_profile

    if program:
        path = Path(program)
        if not path.is_file():
            raise IngestError("part program not found", file=program)
        recording.attachments[PROGRAM_ATTACHMENT] = path.read_bytes()
        recording.metadata.setdefault("program", path.name)
    if profile:
        loaded = load_profile(profile)
        recording.attachments[PROFILE_ATTACHMENT] = loaded.to_toml().encode("utf-8")
        recording.metadata.setdefault("machine", loaded.name)
    if machine:
        recording.metadata["machine"] = machine
    if notes:
        recording.metadata["notes"] = notes
    fill_session_defaults(recording)


def fill_session_defaults(recording) -> None:
    """Nominal rate (median spacing of the densest stream) and start time (if t_ns is wall-clock time)
    where the reader left them out; every standard metadata key present."""
    import numpy as np
    import pandas as pd

    tables = [t for t in recording.streams.values() if len(t) > 1]
    densest = max(tables, key=len) if tables else None
    if densest is not None and not recording.metadata.get("nominal_rate_hz"):
        step = float(np.median(np.diff(densest["t_ns"].to_numpy())))
        if step > 0:
            recording.metadata["nominal_rate_hz"] = f"{1e9 / step:.6g}"
    t0 = recording.t_range_ns[0]
    if not recording.metadata.get("start_time") and t0 > 10**18:  # after 2001: an epoch time, not a relative one
        recording.metadata["start_time"] = pd.Timestamp(t0, tz="UTC").isoformat()
    for key in ("machine", "controller", "units", "nominal_rate_hz", "start_time", "notes"):
        recording.metadata.setdefault(key, "")
