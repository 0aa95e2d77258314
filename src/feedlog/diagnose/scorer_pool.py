"""A scorer's recordings simulated on several processes at once.

A many-cause diagnosis asks its timing `Scorer` for thousands of profiles, one after another (grid
points, Brent steps, least-squares probes: each depends on the last), and every request needs the
residual of every recording (or of all but a held-out one). The recordings are independent of each
other, so a `ScorerPool` shares each request's recordings out over this process and forked worker
processes (the costliest recording first, each to the least loaded process), and a sequential search
uses the machine's cores.

The workers are forks of this process made when the pool starts: they hold the scorer's recordings,
segments and baseline simulations without sending them anywhere (pickled, three recordings' prepared
cases are megabytes); a request carries the override values (a few numbers), a reply the residual
arrays (one number per segment). A worker computes its share with the scorer's own code on the same
data, so the residuals, and every answer built on them, are those of a serial run bit for bit
(`tests/diagnose/test_scorer_pool.py`). A worker that fails or dies leaves its share to this process,
which then computes it itself (a bug raises here, as it would serially). `close()` stops the workers;
the scorer then computes serially again.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from feedlog.diagnose.fit import Scorer
from feedlog.profile import MachineProfile

JOIN_S = 5.0   # how long close() waits for a worker to stop before terminating it


def _serve(scorer: Scorer, conn, inherited: Sequence[Any]) -> None:
    """A worker's loop: (values, recordings) -> (True, ({recording: residual}, simulations)), until None."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # an interrupt is the parent's to handle
    for other in inherited:                       # the parent's ends of earlier workers' pipes
        other.close()
    from feedlog.diagnose import keys

    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        values, cases = msg
        try:
            profile = keys.with_values(scorer.profile, values) if values else scorer.profile
            before = scorer.simulations
            out = scorer.compute_here(values, profile, cases)
            conn.send((True, (out, scorer.simulations - before)))
        except Exception as exc:  # noqa: BLE001 - the parent computes the share itself and meets it there
            conn.send((False, repr(exc)))


def share_out(cases: Sequence[int], costs: Sequence[float], processes: int) -> list[list[int]]:
    """`cases` shared over `processes` (the first is this one): the costliest first, each to the least
    loaded process (ties: the lowest, so this process takes work before a worker does)."""
    shares: list[list[int]] = [[] for _ in range(processes)]
    load = [0.0] * processes
    for i in sorted(cases, key=lambda i: (-costs[i], i)):
        k = int(np.argmin(load))
        shares[k].append(i)
        load[k] += costs[i]
    return shares


class ScorerPool:
    """`processes` - 1 forked workers computing `scorer`'s residuals with this process; attached to the
    scorer (`scorer.pool`) until `close()`. Use as a context manager."""

    def __init__(self, scorer: Scorer, processes: int) -> None:
        self.scorer = scorer
        self.costs = self._costs(scorer)
        self.workers: list[tuple[Any, Any]] = []   # (process, this end of its pipe)
        ctx = mp.get_context("fork")
        for _ in range(max(0, min(processes, len(scorer.cases)) - 1)):
            here, there = ctx.Pipe()
            proc = ctx.Process(target=_serve, args=(scorer, there, [c for _, c in self.workers]), daemon=True,
                               name="feedlog-scorer")
            try:
                proc.start()
            except (AssertionError, OSError):  # a daemonic process (a pool's worker) may have no children
                here.close()
                there.close()
                break
            there.close()
            self.workers.append((proc, here))
        if self.workers:
            scorer.pool = self

    @staticmethod
    def _costs(scorer: Scorer) -> list[float]:
        """What one residual of each recording costs, to share the requests out (it changes no result,
        only who computes it): on the timing level the seconds one simulation of the diagnosed profile
        takes here, elsewhere the recording's rows."""
        if scorer.level != "timing":
            return [float(len(w)) for w in scorer.weights]
        from feedlog.sim import simulate

        out = []
        for case in scorer.cases:
            t0 = time.perf_counter()
            simulate(case.sim_input, scorer.profile)
            out.append(time.perf_counter() - t0)
        return out

    def compute(self, values: Mapping[str, Any], profile: MachineProfile, cases: Sequence[int]
                ) -> dict[int, np.ndarray | None]:
        """The residuals of recordings `cases` for base + `values` (= `profile`): the workers' shares sent
        first, this process' own computed meanwhile, then the workers' collected."""
        shares = share_out(cases, self.costs, 1 + len(self.workers))
        sent, out = [], {}
        for (proc, conn), share in zip(list(self.workers), shares[1:]):
            if not share:
                continue
            try:
                conn.send((dict(values), share))
                sent.append((proc, conn, share))
            except (OSError, ValueError):
                self._lost(proc, conn)
                shares[0] += share
        out.update(self.scorer.compute_here(values, profile, shares[0]))
        for proc, conn, share in sent:
            try:
                ok, payload = conn.recv()
            except (EOFError, OSError):
                ok, payload = False, None
                self._lost(proc, conn)
            if ok:
                res, sims = payload
                out.update(res)
                self.scorer.simulations += sims
            else:  # computed here: the same result, or the same error raised here
                out.update(self.scorer.compute_here(values, profile, share))
        return out

    def _lost(self, proc, conn) -> None:
        self.workers = [(p, c) for p, c in self.workers if p is not proc]
        conn.close()
        if proc.is_alive():
            proc.terminate()
        if not self.workers and self.scorer.pool is self:
            self.scorer.pool = None

    def close(self) -> None:
        for proc, conn in self.workers:
            try:
                conn.send(None)
            except (OSError, ValueError):
                pass
        for proc, conn in self.workers:
            proc.join(JOIN_S)
            if proc.is_alive():
                proc.terminate()
                proc.join(JOIN_S)
            conn.close()
        self.workers = []
        if self.scorer.pool is self:
            self.scorer.pool = None

    def __enter__(self) -> ScorerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
