"""PNG plots drawn in a worker process while the caller goes on (the demo's .rrd logging, the next
recording's overlays): matplotlib is the slow part of writing the demo's outputs (about 0.15 s of CPU per
feed plot, mostly ticks and text), and on two cores it can run beside the rest.

`PlotWorker.submit` sends one recording's `ViewData` to the worker (pickled: a few MB at most) and
returns at once; at most `in_flight` plots wait, so the caller's memory does not grow with a backlog
(it waits for the oldest). `results()` gives each submission's {kind: path} in order; an error in the
worker is raised there, as `plot_view` would have raised it. `workers=0` draws in the caller.
The worker is started with "spawn": the caller may hold torch's threads, which a fork would copy
in an undefined state.
"""

from __future__ import annotations

import multiprocessing
from collections import deque
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

from feedlog.viz.plots import plot_view
from feedlog.viz.prepare import ViewData


class PlotWorker:
    def __init__(self, workers: int = 1, *, in_flight: int = 3) -> None:
        self.pool = (ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
                     if workers > 0 else None)
        self.in_flight = max(1, in_flight)
        self.pending: deque[tuple[str, Future]] = deque()
        self.done: dict[str, dict[str, Path]] = {}

    def submit(self, key: str, data: ViewData, out_dir: Path, *, stem: str,
               kinds: tuple[str, ...] | None = None) -> None:
        """Plot `data` as `plot_view` does; `key` names the result."""
        if self.pool is None:
            self.done[key] = plot_view(data, out_dir, stem=stem, kinds=kinds)
            return
        while len(self.pending) >= self.in_flight:
            self._collect_oldest()
        self.pending.append((key, self.pool.submit(plot_view, data, out_dir, stem=stem, kinds=kinds)))

    def _collect_oldest(self) -> None:
        key, future = self.pending.popleft()
        self.done[key] = future.result()

    def results(self) -> dict[str, dict[str, Path]]:
        """Every submission's plots ({key: {kind: path}}), once all are drawn."""
        while self.pending:
            self._collect_oldest()
        return self.done

    def close(self) -> None:
        if self.pool is not None:
            for _, future in self.pending:
                future.cancel()
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None

    def __enter__(self) -> PlotWorker:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
