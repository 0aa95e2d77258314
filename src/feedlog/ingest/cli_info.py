"""`feedlog info REC [--json] [--recover]`: summarise a recording."""

from __future__ import annotations

import argparse
import json

from feedlog.ingest.data_checks import CHECK_KEYS, run_checks
from feedlog.ingest.reader import read_recording
from feedlog.ingest.summary import format_summary, summarize


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", help="a feedlog recording (.mcap)")
    parser.add_argument("--json", action="store_true", help="print duration_s, streams and dropped_frames as JSON")
    parser.add_argument("--recover", action="store_true",
                        help="summarise what a cut-off file holds (a killed logger, a full disk) instead of failing")


def run(args: argparse.Namespace) -> int:
    recording = read_recording(args.recording, recover=args.recover)
    info = summarize(recording)
    # what the data checks find, for recordings imported before a check existed (or recorded live)
    info["checks"] = {**{k: v for k, v in recording.metadata.items() if k in CHECK_KEYS}, **run_checks(recording)}
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(format_summary(info))
        for key, text in info["checks"].items():
            print(f"warning: {key}: {text}")
    return 0
