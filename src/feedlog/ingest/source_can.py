"""`feedlog record --source can`: record any python-can bus decoded with a DBC.

`--interface virtual --channel NAME` works anywhere (in-process); on a machine: `socketcan` with
`can0`, `pcan` with `PCAN_USBBUS1`, ... Frames are timestamped by python-can (hardware timestamps
where the interface has them).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from feedlog.errors import IngestError
from feedlog.ingest.live import record_bus


STOPS_ON_EVENT = True  # cli_record: SIGINT/SIGTERM set args.stop_event


def add_arguments(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--interface", default="socketcan", help="python-can interface (socketcan, pcan, virtual, ...)")
    group.add_argument("--channel", help="bus channel (can0, PCAN_USBBUS1, a virtual channel name, ...)")
    group.add_argument("--bitrate", type=int, help="bitrate in bit/s where the interface needs one")


def open_bus(interface: str, channel: str | None, bitrate: int | None = None, **kwargs: Any):
    import can

    options = {"interface": interface, "channel": channel, **kwargs}
    if bitrate:
        options["bitrate"] = bitrate
    try:
        return can.Bus(**options)
    except (can.CanError, ValueError, OSError, ImportError, NotImplementedError) as exc:
        raise IngestError(f"cannot open CAN bus {interface}:{channel}: {exc}") from None


def record(args: argparse.Namespace) -> dict[str, Any]:
    extra = {"rx_queue_size": 200_000} if args.interface == "virtual" else {}  # bounded, like a driver buffer
    bus = open_bus(args.interface, args.channel, args.bitrate, **extra)
    try:
        from feedlog.ingest.cli_record import session_attachments

        metadata, attachments = session_attachments(args)
        metadata.update({"source": f"can {args.interface}:{args.channel}", "controller": metadata.get("controller") or ""})
        return record_bus(bus, args.out, dbc=args.dbc, metadata=metadata, attachments=attachments,
                          overwrite=args.overwrite, stop=getattr(args, "stop_event", None),
                          duration_s=args.duration_s, progress=None if args.quiet else sys.stderr)
    finally:
        bus.shutdown()
