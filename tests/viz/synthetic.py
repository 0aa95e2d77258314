"""Synthetic inputs for viz tests: a square toolpath driven at a trapezoidal feed, built in numpy."""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.ingest.recording import Recording

CORNERS = np.array([[0, 0, 0], [20, 0, 0], [20, 10, 0], [0, 10, 0], [0, 0, 0]], dtype=np.float64)
FEED_MM_MIN = 1200.0
FIRST_LINE = 10  # program line of block 0


def program_blocks(corners: np.ndarray = CORNERS, feed: float = FEED_MM_MIN) -> pd.DataFrame:
    """A minimal block table: one G1 block per edge of the square (block k on line FIRST_LINE + k)."""
    n = len(corners) - 1
    return pd.DataFrame({
        "block": np.arange(n, dtype=np.int32), "line": np.arange(FIRST_LINE, FIRST_LINE + n, dtype=np.int32),
        "kind": pd.Categorical(["linear"] * n),
        "x0_mm": corners[:-1, 0], "y0_mm": corners[:-1, 1], "z0_mm": corners[:-1, 2],
        "x_mm": corners[1:, 0], "y_mm": corners[1:, 1], "z_mm": corners[1:, 2],
        "feed_mm_min": np.full(n, feed),
    })


def motion(*, rate_hz: float, feed: float = FEED_MM_MIN, accel_mm_s2: float = 500.0,
           corners: np.ndarray = CORNERS, t0_ns: int = 0, lead_s: float = 0.0):
    """Sampled exact-stop motion along `corners`: positions, path feed and active block per sample."""
    v = feed / 60.0
    t_list, pos_list, feed_list, block_list = [], [], [], []
    t_offset = lead_s
    if lead_s > 0:  # standing still before the program starts
        tt = np.arange(0.0, lead_s, 1.0 / rate_hz)
        t_list.append(tt)
        pos_list.append(np.repeat(corners[:1], len(tt), axis=0))
        feed_list.append(np.zeros(len(tt)))
        block_list.append(np.full(len(tt), -1))
    for k in range(len(corners) - 1):
        a, b = corners[k], corners[k + 1]
        length = float(np.linalg.norm(b - a))
        t_acc = v / accel_mm_s2
        d_acc = 0.5 * accel_mm_s2 * t_acc ** 2
        if 2 * d_acc > length:  # triangular profile
            t_acc = np.sqrt(length / accel_mm_s2)
            d_acc, t_flat, vp = length / 2, 0.0, accel_mm_s2 * t_acc
        else:
            t_flat, vp = (length - 2 * d_acc) / v, v
        dur = 2 * t_acc + t_flat
        tt = np.arange(0.0, dur, 1.0 / rate_hz)
        s = np.where(tt < t_acc, 0.5 * accel_mm_s2 * tt ** 2,
                     np.where(tt < t_acc + t_flat, d_acc + vp * (tt - t_acc),
                              length - 0.5 * accel_mm_s2 * (dur - tt) ** 2))
        sp = np.where(tt < t_acc, accel_mm_s2 * tt, np.where(tt < t_acc + t_flat, vp, accel_mm_s2 * (dur - tt)))
        t_list.append(t_offset + tt)
        pos_list.append(a + np.outer(s / length, b - a))
        feed_list.append(sp * 60.0)
        block_list.append(np.full(len(tt), k))
        t_offset += dur
    t = np.concatenate(t_list)
    return (t0_ns + np.rint(t * 1e9).astype(np.int64), np.concatenate(pos_list), np.concatenate(feed_list),
            np.concatenate(block_list))


def recording(*, rate_hz: float = 1000.0, with_feed: bool = True, five_axis: bool = False,
              t0_ns: int = 1_700_000_000_000_000_000, lead_s: float = 0.2) -> Recording:
    t, pos, feed, block = motion(rate_hz=rate_hz, t0_ns=t0_ns, lead_s=lead_s)
    axes = pd.DataFrame({"t_ns": t, "x_mm": pos[:, 0], "y_mm": pos[:, 1], "z_mm": pos[:, 2]})
    if five_axis:
        axes["a_deg"] = np.linspace(0.0, 30.0, len(t))
        axes["c_deg"] = np.linspace(0.0, 90.0, len(t))
    streams = {"axes": axes}
    if with_feed:
        streams["feed"] = pd.DataFrame({"t_ns": t, "feed_mm_min": feed,
                                        "requested_feed_mm_min": np.full(len(t), FEED_MM_MIN)})
    # the line stream only changes when the line changes (as a controller would publish it)
    line = np.where(block >= 0, block + FIRST_LINE, 0)
    change = np.concatenate([[0], np.flatnonzero(np.diff(line)) + 1])
    streams["line"] = pd.DataFrame({"t_ns": t[change], "line": line[change].astype(np.int64)})
    return Recording(streams=streams, metadata={"machine": "synthetic", "units": "mm"}, source="synthetic.mcap")


def sim_result(*, accel_mm_s2: float = 700.0, rate_hz: float = 1000.0):
    """Series and block table shaped like SimResult (time from 0), with a different acceleration."""
    t, pos, feed, block = motion(rate_hz=rate_hz, accel_mm_s2=accel_mm_s2)
    series = pd.DataFrame({"t_ns": t, "x_mm": pos[:, 0], "y_mm": pos[:, 1], "z_mm": pos[:, 2],
                           "feed_mm_min": feed, "block": block.astype(np.int32)})
    series["line"] = series["block"] + FIRST_LINE
    g = series.groupby("block")["t_ns"]
    blocks = pd.DataFrame({"block": g.min().index.to_numpy(), "t_start_ns": g.min().to_numpy(),
                           "t_end_ns": g.max().to_numpy()})
    blocks["duration_s"] = (blocks["t_end_ns"] - blocks["t_start_ns"]) / 1e9
    return series, blocks


def cl_points(corners: np.ndarray = CORNERS) -> pd.DataFrame:
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(corners, axis=0), axis=1))])
    return pd.DataFrame({"block": np.concatenate([[0], np.arange(len(corners) - 1)]),
                         "x_mm": corners[:, 0], "y_mm": corners[:, 1], "z_mm": corners[:, 2], "s_mm": s})


def program_text() -> str:
    """G-code whose motion blocks sit on lines FIRST_LINE.. and trace CORNERS at FEED_MM_MIN (exact stop)."""
    head = ["%", "(synthetic square for viz tests)"] + ["(pad)"] * (FIRST_LINE - 4) + ["G21 G90 G94 G17 G61"]
    moves = [f"G1 X{x:g} Y{y:g} Z{z:g}" + (f" F{FEED_MM_MIN:g}" if k == 0 else "")
             for k, (x, y, z) in enumerate(CORNERS[1:])]
    return "\n".join(head + moves + ["M30", "%"]) + "\n"


def recording_with_attachments(profile_toml: bytes, **kwargs) -> Recording:
    """A synthetic recording carrying its program and machine profile, as a recorder writes it."""
    rec = recording(**kwargs)
    rec.attachments["program.ngc"] = program_text().encode()
    rec.attachments["profile.toml"] = profile_toml
    return rec


def cycle_time_s(**kwargs) -> float:
    """First block start to last block end of the synthetic motion."""
    t, _, _, block = motion(rate_hz=1000.0, **kwargs)
    moving = t[block >= 0]
    return (moving[-1] - moving[0]) / 1e9
