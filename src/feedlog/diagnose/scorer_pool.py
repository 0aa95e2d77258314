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
WATCH = 0.1    # weight of the latest request in the running means of costs and of the pool's pace
SLOWER = 0.95  # the pool pauses when its requests take this share of the serial time or more ...
PAUSE = 200    # ... for this many requests (doubled after each pause, up to 16 times), then is tried again
TRIAL = 20     # requests on the pool before its pace is judged


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
            out, seconds = timed(scorer, values, profile, cases)
            conn.send((True, (out, scorer.simulations - before, seconds)))
        except Exception as exc:  # noqa: BLE001 - the parent computes the share itself and meets it there
            conn.send((False, repr(exc)))


def timed(scorer: Scorer, values: Mapping[str, Any], profile: MachineProfile, cases: Sequence[int]
          ) -> tuple[dict[int, np.ndarray | None], dict[int, float]]:
    """`scorer.compute_here` one recording at a time: (residuals, seconds each took)."""
    out, seconds = {}, {}
    for i in cases:
        t0 = time.perf_counter()
        out.update(scorer.compute_here(values, profile, [i]))
        seconds[i] = time.perf_counter() - t0
    return out, seconds


def share_out(cases: Sequence[int], costs: Sequence[float], processes: int) -> list[list[int]]:
    """`cases` shared over `processes` (the first is this one): the costliest first, each to the least
    loaded process; on a tie a worker's (this process also runs the search between requests)."""
    shares: list[list[int]] = [[] for _ in range(processes)]
    load = [1e-12] + [0.0] * (processes - 1)
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
        self.pace, self.requests, self.paused, self.pauses = 0.0, 0, 0, 0
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

    def _here(self, values: Mapping[str, Any], profile: MachineProfile, cases: Sequence[int]
              ) -> dict[int, np.ndarray | None]:
        out, seconds = timed(self.scorer, values, profile, cases)
        self._learn(seconds)
        return out

    def _learn(self, seconds: Mapping[int, float]) -> None:
        for i, s in seconds.items():
            self.costs[i] += WATCH * (s - self.costs[i])

    def compute(self, values: Mapping[str, Any], profile: MachineProfile, cases: Sequence[int]
                ) -> dict[int, np.ndarray | None]:
        """The residuals of recordings `cases` for base + `values` (= `profile`). Here serially while
        the pool pauses; else the workers' shares sent first, this process' own computed meanwhile, the
        workers' collected, and the pool's pace measured: on a machine whose cores are busy with other
        work a worker gets no core of its own and the pool is no faster than serial (measured on this
        2-core machine while another session kept a core busy: two sides of 3 ms each took 5.7 ms a
        round trip; the pool's requests 1.06-1.11 of the serial time), and then the pool pauses
        (`SLOWER`, `PAUSE`). Who computes a residual changes nothing in it."""
        if self.paused > 0:
            self.paused -= 1
            return self._here(values, profile, cases)
        t0 = time.perf_counter()
        out = self._pooled(values, profile, cases)
        pace = (time.perf_counter() - t0) / max(sum(self.costs[i] for i in cases), 1e-9)
        self.pace = pace if self.requests == 0 else self.pace + WATCH * (pace - self.pace)
        self.requests += 1
        if self.requests >= TRIAL and self.pace >= SLOWER:
            self.paused, self.requests, self.pauses = PAUSE << min(self.pauses, 4), 0, self.pauses + 1
        return out

    def _pooled(self, values: Mapping[str, Any], profile: MachineProfile, cases: Sequence[int]
                ) -> dict[int, np.ndarray | None]:
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
        out.update(self._here(values, profile, shares[0]))
        for proc, conn, share in sent:
            try:
                ok, payload = conn.recv()
            except (EOFError, OSError):
                ok, payload = False, None
                self._lost(proc, conn)
            if ok:
                res, sims, seconds = payload
                out.update(res)
                self.scorer.simulations += sims
                self._learn(seconds)
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
