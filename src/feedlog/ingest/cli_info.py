"""`feedlog info REC [--json] [--recover]`: summarise a recording."""

from __future__ import annotations

import argparse
import json

from feedlog.ingest.reader import read_recording
from feedlog.ingest.summary import format_summary, summarize


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", help="a feedlog recording (.mcap)")
    parser.add_argument("--json", action="store_true", help="print duration_s, streams and dropped_frames as JSON")
    parser.add_argument("--recover", action="store_true",
                        help="summarise what a cut-off file holds (a killed logger, a full disk) instead of failing")


def run(args: argparse.Namespace) -> int:
    info = summarize(read_recording(args.recording, recover=args.recover))
    print(json.dumps(info, indent=2) if args.json else format_summary(info))
    return 0
