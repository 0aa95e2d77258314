"""Windowed simulation: a program of any length, simulated window by window in bounded memory, with
the result of simulating it at once (the same per-block times and series, to the last bit on every
bundled program; tests/sim/test_window.py).

    run = WindowedSimulation("part.ngc", "linuxcnc-xyz", series=True)
    for window in run:              # SimWindow: .blocks (per-block table rows), .series (samples)
        ...
    run.result                      # cycle_time_s, cam_time_s, blocks, notes, mechanism parameters

The chain is the one `simulate` runs, in stages that each hold a few windows of rows:

1. The program is read in chunks (toolpath.ProgramReader) and its rows prepared (`prepare_blocks`).
2. `limits` mechanisms run on a window of rows. A mechanism whose result for the last rows depends
   on rows to come says so (`Window.pending`): the open merge chain of `naive_cam`, the last moving row
   of `reversal_dwell`, rows whose C axis waits for a defined orientation in `trunnion`, and always
   the last row (the program's last one stops). Those rows are done again with the next window, each
   mechanism starting from the state it handed over (`Window.carry`).
3. The path pieces are built and the corner law runs on windows of pieces with `CONTEXT` pieces of
   context on either side: a junction's decisions involve the pieces next to it only.
4. The interpolator's windowed form (`Mechanism.stream`) plans the pieces: the look-ahead planner
   finalises a piece once no later piece can change its speed (feedlog.sim.stream_plan).
5. Block times and series samples follow from each planned window (`PlanSampler`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.errors import SimulationError
from feedlog.profile import MachineProfile, load_profile
from feedlog.registry import TargetMissing, import_target
from feedlog.sim.cam import cam_block_times
from feedlog.sim.context import Context, Window, one_row_per_block
from feedlog.sim.mechanism import Mechanism, MechanismSpec, resolve_mechanisms
from feedlog.sim.path import Blocks, Pieces, ProgramArrays, build_pieces, prepare_blocks
from feedlog.sim.simulate import mechanism_params
from feedlog.sim.stream_plan import LINE_SPAN, Chunk
from feedlog.toolpath.schema import AXIS_UNITS
from feedlog.units import MAX_TIME_S, seconds_to_ns

WINDOW = 1 << 15     # rows and pieces a stage works on at once
CONTEXT = 3          # pieces of context either side of a corner-law window
PASSIVE_KINDS = ("feedback", "measurement")   # never change the commanded motion


@dataclass
class SimWindow:
    """One window's output: rows of the per-block table (block, line, t_start_ns, t_end_ns,
    duration_s) and, when asked for, the samples (t_ns, axes, feed_mm_min, block, line)."""

    blocks: pd.DataFrame
    series: pd.DataFrame | None = None


@dataclass
class WindowedResult:
    """What `SimResult.summary` reports, for a windowed run."""

    profile: MachineProfile
    mechanisms: list[Mechanism]
    cycle_time_s: float = 0.0
    cam_time_s: float = 0.0
    blocks: int = 0
    samples: int = 0
    rows: int = 0
    notes: dict[str, int] = field(default_factory=dict)

    @property
    def mechanism_params(self) -> dict[str, dict[str, Any]]:
        return mechanism_params(self.mechanisms)

    def summary(self) -> dict[str, Any]:
        return {"profile": self.profile.name, "cycle_time_s": round(self.cycle_time_s, 6),
                "cam_time_s": round(self.cam_time_s, 6), "blocks": int(self.blocks),
                "mechanisms": self.mechanism_params}


def unsupported(chain: list[Mechanism]) -> list[str]:
    """Names of mechanisms of the chain that have no windowed form."""
    return [m.name for m in chain if m.kind not in PASSIVE_KINDS and not (m.windowed or m.stream)]


def _table_batches(table: pd.DataFrame, rows: int) -> Iterator[pd.DataFrame]:
    for lo in range(0, max(len(table), 1), rows):
        yield table.iloc[lo:lo + rows]


class WindowedSimulation:
    """`simulate` over a program of any length (a path, G-code text, a Program or a block table),
    window by window. Iterate for the windows; `result` once the iteration is over."""

    def __init__(self, program, profile: MachineProfile | str | Path, *, mechanisms: MechanismSpec = None,
                 dt_s: float | None = None, series: bool = False, window: int = WINDOW, lenient: bool = False,
                 name: str | None = None, chunk_bytes: int | None = None) -> None:
        self.profile = profile if isinstance(profile, MachineProfile) else load_profile(profile)
        if dt_s is not None and not 0 < dt_s <= 1:
            raise SimulationError(f"output period dt_s must be above 0 and at most 1 s, got {dt_s}")
        self.dt_s = dt_s or self.profile.interpolator.interpolation_period_s
        self.chain = resolve_mechanisms(self.profile, mechanisms)
        missing = unsupported(self.chain)
        if missing:
            raise SimulationError(f"mechanism(s) {', '.join(missing)} cannot run window by window; simulate the "
                                  "program at once (feedlog.sim.simulate)")
        self.interpolator = next(m for m in self.chain if m.kind == "interpolator")
        self.window = max(int(window), 2 * CONTEXT + 2)
        self.series = series
        self.result = WindowedResult(profile=self.profile, mechanisms=self.chain)
        self.reader = None
        self._slice: int | None = None     # rows of a prepared batch handed on at once (None: all)
        if isinstance(program, (str, Path)):
            from feedlog.toolpath.stream import open_program_reader

            kw = {} if chunk_bytes is None else {"chunk_bytes": chunk_bytes}
            self.reader = open_program_reader(program, lenient=lenient, name=name, **kw)
            self._tables = iter(self.reader)
        else:
            table = getattr(program, "blocks", program)
            if not isinstance(table, pd.DataFrame):
                raise SimulationError(f"expected a Program, a block table or a path, got {type(program).__name__}")
            # rows prepared in large batches (prepare_blocks is row by row), handed on a window at a time
            self._tables = _table_batches(table, max(self.window, WINDOW))
            self._slice = self.window
        self._notes: dict[str, int] = {}

    # -- 1. rows -------------------------------------------------------------------------------------
    def _raw(self) -> Iterator[Blocks]:
        for table in self._tables:
            arrays = ProgramArrays(table)
            blocks = prepare_blocks(arrays, self.profile, last=False)
            blocks.extra["first_block"] = blocks.block.copy()
            self.result.cam_time_s += float(cam_block_times(blocks).sum())
            self.result.rows += len(table)
            step = self._slice or max(len(blocks), 1)
            for lo in range(0, len(blocks), step):
                yield blocks if step >= len(blocks) else blocks.take(np.arange(lo, min(lo + step, len(blocks))))

    # -- 2. limits -----------------------------------------------------------------------------------
    def _limited(self, raw: Iterator[Blocks]) -> Iterator[Blocks]:
        limits = [m for m in self.chain if m.kind == "limits"]
        pending: Blocks | None = None
        state: dict[str, dict] = {}
        ended = False
        while not ended:
            parts, count = [pending], 0     # new rows: at least a window's worth beyond the pending ones
            while count < self.window:
                nxt = next(raw, None)
                if nxt is None:
                    ended = True
                    break
                parts.append(nxt)
                count += len(nxt)
            if not count and pending is None:
                return
            buf = Blocks.concat(parts)
            work = buf.take(np.arange(len(buf)))
            if ended:          # the program's last row stops
                work.stop_after[-1] = True
                work.exact_path[-1] = False
            window = Window(last=ended, state=state)
            if not ended:
                window.pending("rows", int(buf.block[-1]))   # the last row stops if it is the program's last
            ctx = Context(profile=self.profile, blocks=work, dt_s=self.dt_s, window=window)
            for mech in limits:
                mech.limit(ctx)
            out = ctx.blocks
            restart = np.iinfo(np.int64).max if ended else int(window.restart())
            final = np.flatnonzero(out.extra["first_block"] < restart)
            kept = out.take(final)
            self._count("merged_blocks", int(np.count_nonzero(buf.block < restart)) - len(kept))
            if "reversal" in kept.extra:
                self._count("reversals", int(np.nansum(kept.extra["reversal"] == 1)))
            state = {name: fn(restart) for name, fn in ctx.window.hand_over.items()} if not ended else {}
            pending = None if ended else buf.take(np.flatnonzero(buf.block >= restart))
            if len(kept):
                yield kept

    def _count(self, name: str, value: int) -> None:
        self._notes[name] = self._notes.get(name, 0) + value

    # -- 3. pieces and corners -----------------------------------------------------------------------
    def _pieces(self, limited: Iterator[Blocks]) -> Iterator[tuple[Chunk, bool]]:
        corners = [m for m in self.chain if m.kind == "corner"] if self.interpolator.uses_corner_law else []
        rows: Blocks | None = None      # limited rows from global row `row0` on
        row0 = 0
        pcs: Pieces | None = None       # pieces (block = global row) from global piece `done - held` on
        held = 0                        # pieces before `done` kept as context
        ended = False
        while True:
            nxt = next(limited, None)
            if nxt is None:
                ended = True
            else:
                base = row0 + (len(rows) if rows is not None else 0)
                new = build_pieces(nxt)
                keep = (new.length > 0) | (new.hold_s > 0)
                new = new if keep.all() else new.take(np.flatnonzero(keep))
                new.block = new.block + base
                rows = Blocks.concat([rows, nxt])
                pcs = Pieces.concat([pcs, new])
            total = len(pcs) if pcs is not None else 0
            while total - held >= self.window + CONTEXT or (ended and total > held):
                hi = total if ended and total - held <= self.window + CONTEXT else held + self.window
                lo_ctx = max(held - CONTEXT, 0)
                hi_ctx = min(hi + CONTEXT, total)
                window = pcs.slice(lo_ctx, hi_ctx)
                first_row, last_row = int(window.block[0]), int(window.block[-1])
                view = rows.take(np.arange(first_row - row0, last_row - row0 + 1))
                window = window.take(np.arange(len(window)))
                window.block = window.block - first_row
                last = ended and hi_ctx == total
                ctx = Context(profile=self.profile, blocks=view, pieces=window, dt_s=self.dt_s,
                              window=Window(last=last, core=(held - lo_ctx, hi - lo_ctx)))
                for mech in corners:
                    mech.corner(ctx)
                for name in ("blend_arcs", "curved_blends", "tangent_junctions", "parabolic_blends", "consumed_lines"):
                    if name in ctx.notes:
                        self._count(name, int(ctx.notes.pop(name)))
                out = ctx.pieces
                line = np.flatnonzero(~out.blend)          # the window's pieces; a blend arc follows its line
                a = int(line[held - lo_ctx])
                b = int(line[hi - lo_ctx]) if hi - lo_ctx < len(line) else len(out)
                core = out.slice(a, b)
                side = {"block": view.block.take(core.block), "line": view.line.take(core.block),
                        "feed": view.feed.take(core.block), "v_axis": view.v_axis.take(core.block),
                        "tol": view.tol.take(core.block),
                        "stop_after": view.stop_after.take(core.block),
                        "feed_scale": (view.extra["feed_scale"].take(core.block) if "feed_scale" in view.extra
                                       else np.ones(len(core)))}
                core.block = core.block + first_row
                yield Chunk(core, side), ended and hi == total
                # keep CONTEXT pieces before the next window, and their rows
                drop = max(hi - CONTEXT, 0)
                pcs = pcs.slice(drop, total)
                total, held = total - drop, hi - drop
                keep_row = int(pcs.block[0]) if len(pcs) else row0 + len(rows)
                rows = rows.take(np.arange(keep_row - row0, len(rows)))
                row0 = keep_row
            if ended:
                return

    # -- 4. and 5. plan, block times, series ---------------------------------------------------------
    def _stream(self):
        try:
            stream_cls = import_target(self.interpolator.stream)
        except TargetMissing as missing:
            raise SimulationError(f"mechanism {self.interpolator.name!r}: its windowed form "
                                  f"{self.interpolator.stream} is not available ({missing})") from None
        if self.interpolator.name == "fir":
            return stream_cls(self.interpolator, self.dt_s,
                              [i for i, a in enumerate(self.profile.axis_names) if a in ("x", "y", "z")])
        planner = stream_cls(int(self.interpolator.lookahead_blocks)) if self.interpolator.name == "lookahead" \
            else stream_cls()
        from feedlog.sim.stream_plan import PlannedStream

        return PlannedStream(planner, self.dt_s)

    def __iter__(self) -> Iterator[SimWindow]:
        stream = self._stream()
        limit = getattr(self.interpolator, "limit_pieces", None)
        chunks = self._pieces(self._limited(self._raw()))
        try:
            for chunk, end in chunks:
                if limit is not None:
                    chunk.pieces = limit(chunk.pieces, chunk.side["feed_scale"], ends_program=end,
                                         v_axis=chunk.side["v_axis"])
                final = stream.push(chunk, end)
                if final is not None:
                    yield self._window(stream, final, end)
            yield self._window(stream, None, True)
        finally:
            if self.reader is not None:
                self.reader.close()
        self._finish(stream)

    def _window(self, stream, final, end: bool) -> SimWindow:
        packed, start, stop = stream.block_times(final, end) if final is not None else stream.close()
        table = _block_table(packed, start, stop)
        self.result.blocks += len(table)
        series = None
        if self.series and final is not None:
            samples = stream.samples(final, end)
            if samples is not None:
                series = self.series_frame(*samples)
                self.result.samples += len(series)
        elif self.series and not self.result.samples:   # no motion at all: one sample at rest, as `simulate`
            k = len(self.profile.axis_names)
            series = self.series_frame(np.zeros(1), np.zeros((1, k)), np.zeros(1), np.zeros(1, np.int64))
            self.result.samples = 1
        return SimWindow(blocks=table, series=series)

    def series_frame(self, t, pos, speed, packed) -> pd.DataFrame:
        """Samples as `SimResult.series` has them (`packed`: block * LINE_SPAN + line)."""
        names = [f"{axis}_{AXIS_UNITS[axis]}" for axis in self.profile.axis_names]
        frame = pd.DataFrame(np.asfortranarray(pos), columns=names, copy=False)
        frame.insert(0, "t_ns", seconds_to_ns(t))
        frame["feed_mm_min"] = speed * 60.0
        frame["block"] = packed // LINE_SPAN
        frame["line"] = packed % LINE_SPAN
        return frame

    def _finish(self, stream) -> None:
        m_start, m_end = stream.motion
        cycle = max(m_end - m_start, 0.0) if np.isfinite(m_start) else 0.0
        if not 0 <= cycle <= MAX_TIME_S:
            raise SimulationError(f"simulated cycle time {cycle:.6g} s is not a time feedlog can count "
                                  f"(0 to {MAX_TIME_S:.0e} s)")
        self.result.cycle_time_s = cycle
        self.result.notes = dict(self._notes)


def _block_table(packed: np.ndarray, start_s: np.ndarray, end_s: np.ndarray) -> pd.DataFrame:
    start_ns = seconds_to_ns(start_s)
    end_ns = seconds_to_ns(end_s)
    block, line, start_ns, end_ns = one_row_per_block((packed // LINE_SPAN).astype(np.int64),
                                                      (packed % LINE_SPAN).astype(np.int64), start_ns, end_ns)
    return pd.DataFrame({"block": block, "line": line,
                         "t_start_ns": start_ns, "t_end_ns": end_ns, "duration_s": (end_ns - start_ns) / 1e9})


def simulate_windowed(program, profile, *, mechanisms: MechanismSpec = None, dt_s: float | None = None,
                      series: bool = False, window: int = WINDOW, **kw) -> tuple[WindowedResult, pd.DataFrame,
                                                                                 pd.DataFrame | None]:
    """All windows gathered in memory: (result, per-block table, series or None). For tests and small
    programs; long ones go window by window to Parquet (feedlog.sim.output)."""
    run = WindowedSimulation(program, profile, mechanisms=mechanisms, dt_s=dt_s, series=series, window=window, **kw)
    blocks, frames = [], []
    for w in run:
        blocks.append(w.blocks)
        if w.series is not None:
            frames.append(w.series)
    table = pd.concat(blocks, ignore_index=True)
    series_frame = pd.concat(frames, ignore_index=True) if frames else None
    return run.result, table, series_frame
