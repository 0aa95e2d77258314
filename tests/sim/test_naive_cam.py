"""The vectorised collinear merge against the sequential loop it replaced (emccanon.cc's test)."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.sim.naive_cam import chains


def loop_chains(p0, p1, cand, tol, max_chain, lead=False):
    """The merge as emccanon.cc walks it, one row at a time (the code feedlog had before)."""
    n = len(p0)
    is_cand = np.zeros(n + 1, bool)
    is_cand[1:n] = cand
    is_cand[0] = lead
    idx = np.flatnonzero(is_cand[1:n]) + 1
    alone = ~is_cand[idx - 1] & ~is_cand[idx + 1]
    out = {int(i): int(i) - 1 for i in idx[alone]}
    chain_start, chain_len, pts, s0, prev = -1, 0, [], None, -2
    for i in idx[~alone].tolist():
        if i != prev + 1 or chain_start < 0:
            chain_start, chain_len, pts, s0 = i - 1, 1, [p1[i - 1].tolist()], p0[i - 1].tolist()
        e_i = p1[i].tolist()
        ok = chain_len <= max_chain
        if ok:
            sx, sy, sz = s0
            mx, my, mz = e_i[0] - sx, e_i[1] - sy, e_i[2] - sz
            mm = mx * mx + my * my + mz * mz
            tol2 = float(tol[i]) * float(tol[i])
            for px, py, pz in pts:
                dx, dy, dz = px - sx, py - sy, pz - sz
                t = 0.0 if mm <= 0 else min(max((dx * mx + dy * my + dz * mz) / mm, 0.0), 1.0)
                ex, ey, ez = dx - t * mx, dy - t * my, dz - t * mz
                if ex * ex + ey * ey + ez * ez > tol2:
                    ok = False
                    break
        if ok:
            out.pop(i - 1, None)
            out[i] = chain_start
            pts.append(e_i)
            chain_len += 1
        else:
            chain_start, chain_len, pts, s0 = i, 1, [e_i], p0[i].tolist()
        prev = i
    return out  # chain end row -> chain start row


def polyline(rng, n, *, turn, step):
    heading = np.cumsum(rng.normal(0.0, turn, n))
    steps = rng.uniform(*step, n)
    pts = np.zeros((n + 1, 3))
    pts[1:, 0] = np.cumsum(steps * np.cos(heading))
    pts[1:, 1] = np.cumsum(steps * np.sin(heading))
    pts[1:, 2] = np.cumsum(rng.normal(0.0, turn * 0.01, n))
    return pts[:-1], pts[1:]


@pytest.mark.parametrize("seed", range(12))
def test_chains_equal_the_sequential_loop(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 3000))
    turn = [0.0, 1e-4, 0.003, 0.03, 0.3][seed % 5]
    p0, p1 = polyline(rng, n, turn=turn, step=(0.01, 0.5))
    if seed % 3 == 0:  # exact collinear stretches (count-limited chains) between the curves
        p1[:, 2] = np.round(p1[:, 2], 1)
        p0[1:] = p1[:-1]
    tol = np.full(n, [0.001, 0.01, 0.05][seed % 3])
    cand = rng.random(n - 1) < [1.0, 0.97, 0.7, 0.4][seed % 4]
    max_chain = [100, 3, 7, 100, 1][seed % 5]
    lead = bool(seed % 2)
    start, end, _ = chains(p0, p1, cand, tol, max_chain, lead_candidate=lead)
    got = dict(zip(end.tolist(), start.tolist()))
    assert got == loop_chains(p0, p1, cand, tol, max_chain, lead)


def test_open_chain_is_the_one_holding_the_last_row():
    rng = np.random.default_rng(5)
    p0, p1 = polyline(rng, 400, turn=0.0, step=(0.1, 0.1))
    tol = np.full(400, 0.01)
    cand = np.ones(399, bool)
    start, end, open_from = chains(p0, p1, cand, tol, 100)
    assert end.tolist() == [100, 201, 302, 399] and open_from == 303   # 101 rows a chain; 303..399 open
    _, _, open_from = chains(p0, p1, np.r_[cand[:-1], False], tol, 100)
    assert open_from == 399                                     # the last row cannot join: alone


def test_remembered_chains_are_the_chains_of_exactly_those_inputs():
    """A fit re-simulates one program thousands of times; the chains are remembered by a digest of the
    inputs: the same inputs give the same chains, any changed input (a point, a pre-test, a tolerance, the
    chain length) is computed again, and a caller changing what it got does not change what comes next."""
    from feedlog.sim.naive_cam import remembered_chains

    rng = np.random.default_rng(11)
    p0, p1 = polyline(rng, 600, turn=0.0, step=(0.1, 0.1))
    tol, cand = np.full(600, 0.01), np.ones(599, bool)
    want = chains(p0, p1, cand, tol, 100)
    got = remembered_chains(p0, p1, cand, tol, 100)
    got[0][:] = -1   # the caller's copy
    again = remembered_chains(p0, p1, cand, tol, 100)
    for a, b in zip(want[:2], again[:2]):
        assert np.array_equal(a, b)
    assert again[2] == want[2]
    cut = cand.copy()
    cut[250] = False
    bent = p1.copy()
    bent[120, 1] += 0.5
    for args in ((p0, p1, cut, tol, 100), (p0, bent, cand, tol, 100), (p0, p1, cand, tol * 0, 100),
                 (p0, p1, cand, tol, 7)):
        fresh, kept = chains(*args), remembered_chains(*args)
        assert np.array_equal(fresh[1], kept[1]) and not np.array_equal(kept[1], want[1])
