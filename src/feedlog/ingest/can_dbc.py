"""Vectorised CAN decoding and encoding driven by a DBC's signal layout (cantools parses the DBC).

cantools decodes one frame per Python call (~0.5 M frames/s). Here each classic-CAN message's
signals become a bit layout (start, length, byte order, sign, scale, offset) applied with numpy to all
frames of that id at once: frames are viewed as 64-bit words (little-endian for Intel signals,
big-endian for Motorola), shifted and masked. Messages the layout cannot express (CAN FD longer than
8 bytes, multiplexed, float signals) fall back to cantools' per-frame decoder.

Frames travel as `CanFrames`: parallel arrays `t_ns`, `can_id`, `data` (N x 8 bytes, zero padded).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import cantools
import numpy as np

from feedlog.errors import IngestError
from feedlog.units import MAX_ABS_T_NS

STREAM_ATTRIBUTE = "FeedlogStream"
SEQ_SIGNAL = "seq"


def seconds_to_us_ns(seconds) -> np.ndarray:
    """python-can's float-second timestamps -> int64 ns, rounded to whole microseconds (a float64 epoch
    time resolves only ~0.2 us, and CAN interfaces and log formats stamp in us or coarser)."""
    return np.rint(np.asarray(seconds, dtype=np.float64) * 1e6).astype(np.int64) * 1000


def frame_problem(msg) -> str | None:
    """Why no CAN bus could have carried the python-can message `msg` (an id beyond 11 or 29 bits, a
    timestamp that is NaN, infinite or beyond int64 nanoseconds), or None."""
    limit = 0x1FFF_FFFF if msg.is_extended_id else 0x7FF
    if not 0 <= msg.arbitration_id <= limit:
        return f"identifier 0x{msg.arbitration_id:X} does not fit {29 if msg.is_extended_id else 11} bits"
    if not (math.isfinite(msg.timestamp) and abs(msg.timestamp) < MAX_ABS_T_NS / 1e9):
        return f"timestamp {msg.timestamp} is not a time"
    return None


def default_dbc_path() -> Path:
    return Path(str(resources.files("feedlog.ingest") / "feedlog_axes.dbc"))


@dataclass
class CanFrames:
    """N CAN frames as arrays: receive time (int64 ns), id, 8 data bytes (zero padded), length."""

    t_ns: np.ndarray
    can_id: np.ndarray
    data: np.ndarray
    dlc: np.ndarray = field(default=None)

    def __post_init__(self) -> None:
        self.t_ns = np.ascontiguousarray(self.t_ns, dtype=np.int64)
        self.can_id = np.ascontiguousarray(self.can_id, dtype=np.uint32)
        self.data = np.ascontiguousarray(self.data, dtype=np.uint8).reshape(-1, 8)
        if self.dlc is None:
            self.dlc = np.full(len(self.t_ns), 8, dtype=np.uint8)
        if not (len(self.t_ns) == len(self.can_id) == len(self.data) == len(self.dlc)):
            raise ValueError("CanFrames arrays differ in length")

    def __len__(self) -> int:
        return len(self.t_ns)

    @classmethod
    def concat(cls, parts: list[CanFrames]) -> CanFrames:
        if not parts:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.uint32), np.zeros((0, 8), np.uint8))
        return cls(np.concatenate([p.t_ns for p in parts]), np.concatenate([p.can_id for p in parts]),
                   np.concatenate([p.data for p in parts]), np.concatenate([p.dlc for p in parts]))


@dataclass(frozen=True)
class SignalLayout:
    name: str
    column: str
    stream: str
    shift: int  # of the raw value's LSB in the little- or big-endian 64-bit word
    length: int
    big_endian: bool
    signed: bool
    scale: float
    offset: float

    @property
    def integer(self) -> bool:
        return self.scale == 1 and self.offset == 0 and float(self.scale).is_integer()


@dataclass
class MessageLayout:
    frame_id: int
    name: str
    signals: list[SignalLayout]
    bulk: bool  # False: decode with cantools frame by frame
    message: object  # the cantools Message

    @property
    def length(self) -> int:
        """Data bytes a frame of this message carries; shorter frames cannot be decoded."""
        return int(self.message.length)

    def decode(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Decode all frames of this id (N x 8 bytes) into physical values per signal."""
        if not self.bulk:
            return self._decode_slow(data)
        return self.decode_words(np.ascontiguousarray(data).view("<u8").ravel())

    def decode_words(self, little: np.ndarray) -> dict[str, np.ndarray]:
        """Decode frames given as little-endian uint64 words (the 8 data bytes of each frame)."""
        out: dict[str, np.ndarray] = {}
        big = little.byteswap() if any(s.big_endian for s in self.signals) else None
        for s in self.signals:
            word = big if s.big_endian else little
            raw = (word >> np.uint64(s.shift)) & np.uint64((1 << s.length) - 1) if s.length < 64 else word
            if s.signed:
                sign = np.uint64(1 << (s.length - 1))
                raw = (raw ^ sign).view(np.int64) - np.int64(1 << (s.length - 1))
            else:
                raw = raw.view(np.int64)
            out[s.name] = raw if s.integer else raw * s.scale + s.offset
        return out

    def encode(self, values: dict[str, np.ndarray]) -> np.ndarray:
        """Physical values per signal (missing ones are 0) -> N x 8 frame bytes."""
        if not self.bulk:
            raise IngestError(f"message {self.name}: vectorised encoding needs a plain classic-CAN layout")
        n = len(next(iter(values.values())))
        little = np.zeros(n, dtype=np.uint64)
        big = np.zeros(n, dtype=np.uint64)
        for s in self.signals:
            if s.name not in values:
                continue
            raw = np.rint((np.asarray(values[s.name], dtype=np.float64) - s.offset) / s.scale).astype(np.int64)
            lo, hi = (-(1 << (s.length - 1)), (1 << (s.length - 1)) - 1) if s.signed else (0, (1 << s.length) - 1)
            if n and (raw.min() < lo or raw.max() > hi):
                worst = raw[np.argmax((raw < lo) | (raw > hi))]
                raise IngestError(f"signal {self.name}.{s.name}: value {worst * s.scale + s.offset} does not fit "
                                  f"{s.length} bits at scale {s.scale}")
            bits = raw.astype(np.uint64) & np.uint64((1 << s.length) - 1)
            if s.big_endian:
                big |= bits << np.uint64(s.shift)
            else:
                little |= bits << np.uint64(s.shift)
        data = little.astype("<u8").view(np.uint8).reshape(n, 8).copy()
        if self.signals and any(s.big_endian for s in self.signals):
            data |= big.astype(">u8").view(np.uint8).reshape(n, 8)
        return data

    def _decode_slow(self, data: np.ndarray) -> dict[str, np.ndarray]:
        rows = [self.message.decode(bytes(row[: self.message.length]), decode_choices=False) for row in data]
        return {s.name: np.array([r.get(s.name, np.nan) for r in rows], dtype=np.float64) for s in self.signals}


def _column_name(name: str, unit: str | None) -> str:
    column = re.sub(r"[^0-9a-zA-Z]+", "_", name).strip("_").lower()
    unit_part = re.sub(r"[^0-9a-zA-Z]+", "_", unit or "").strip("_").lower()
    if unit_part and not column.endswith(unit_part):
        column = f"{column}_{unit_part}"
    return column or "value"


def _attribute(owner, default: str) -> str:
    attrs = getattr(getattr(owner, "dbc", None), "attributes", None) or {}
    attr = attrs.get(STREAM_ATTRIBUTE)
    return str(attr.value) if attr is not None and str(attr.value) else default


class DbcLayout:
    """All messages of a DBC as layouts, keyed by frame id."""

    def __init__(self, path: str | os.PathLike | None = None) -> None:
        self.path = Path(path) if path else default_dbc_path()
        try:
            self.db = cantools.database.load_file(str(self.path), strict=True)
        except FileNotFoundError:
            raise IngestError("DBC file not found", file=str(self.path)) from None
        except Exception as exc:  # cantools raises several parse error types
            raise IngestError(f"cannot parse DBC: {exc}", file=str(self.path)) from None
        self.messages: dict[int, MessageLayout] = {}
        for message in self.db.messages:
            self.messages[message.frame_id] = self._layout(message)

    def _layout(self, message) -> MessageLayout:
        stream_default = _attribute(message, _column_name(message.name, None))
        bulk = message.length <= 8 and not message.is_multiplexed()
        signals = []
        for s in message.signals:
            bulk &= not s.is_float
            if s.byte_order == "little_endian":
                shift, big = s.start, False
            else:  # Motorola: start is the MSB in DBC sawtooth numbering; count from the 64-bit word's MSB
                msb = (s.start // 8) * 8 + (7 - s.start % 8)
                shift, big = 63 - (msb + s.length - 1), True
            signals.append(SignalLayout(name=s.name, column=_column_name(s.name, s.unit),
                                        stream=_attribute(s, stream_default), shift=shift, length=s.length,
                                        big_endian=big, signed=s.is_signed, scale=float(s.scale),
                                        offset=float(s.offset)))
        return MessageLayout(message.frame_id, message.name, signals, bulk, message)

    def by_name(self, name: str) -> MessageLayout:
        for layout in self.messages.values():
            if layout.name == name:
                return layout
        raise IngestError(f"DBC has no message {name!r}", file=str(self.path))

    def source_text(self) -> bytes:
        return self.path.read_bytes()
