"""Which blend LinuxCNC 2.9 uses at a continuous-mode corner: a blend arc, a parabolic blend or the
tangent (kink) speed.

Source: LinuxCNC 2.9 src/emc/tp/tp.c `tpChooseBestBlend`, `estimateParabolicBlendPerformance`,
`tpComputeBlendVelocity`, `tpCalculateTriangleVel`; tc.c `tcGetTangentialMaxAccel`,
`tcCircleStartAccelUnitVector`. When a move is queued, the planner rates the corner it makes with the
previous one three ways and takes the best (a tie goes to the parabolic blend, then to the tangent):

- a blend arc: its maximum speed;
- the tangent rule: the kink speed;
- a parabolic blend: half its net speed, sin(theta) (v_this + v_next) / 2, halved because a parabolic
  blend halves the acceleration of both moves. Each move's blend speed is what it reaches over half its
  length (it is not finalized yet) with its tangential acceleration at that moment: its own limit,
  reduced by the kink share the tangent check just set, halved by the parabolic end condition and, on a
  programmed arc, halved again (an arc's share from its speed is worked out only when it is
  finalized); both within one blend time, and within the G64 P tolerance where one is given. theta is
  the half-angle between the previous move's end tangent and the next move's start acceleration
  direction (on an arc, tilted toward its centre by the normal acceleration at half the feed).

On tight arcs the blend arc is short and slow and the parabolic blend wins: plasmatest's 0.92 mm and
3.84 mm cut-in arcs turn into their first line that way (the recorded speed dips while the reported
feed keeps rising, and the line switches at the end of the arc, not where a blend arc would start).
"""

from __future__ import annotations

import math

import numpy as np

BLEND_ACC_RATIO_TANGENTIAL = 0.5
MIN_ARC_ANGLE = 1e-3            # TP_MIN_ARC_ANGLE: below pi/2 - this, the tolerance caps the blend speed


def parabolic_performance(pc, j: np.ndarray, u1: np.ndarray, u2: np.ndarray, *, feed: np.ndarray,
                          v_target: np.ndarray, tol: np.ndarray, kink_ratio: float, lin) -> np.ndarray:
    """LinuxCNC's rating of a parabolic blend at junctions j (piece j into piece j + 1): half the net
    blend speed. `feed`: per piece, the programmed feed (reqvel); `v_target`: per piece, its maximum
    target speed (feed capped by axes, one servo cycle, and on an arc the centripetal speed); `tol`: per
    junction, the G64 P tolerance (0 or NaN: none)."""
    p1, p2 = j, j + 1
    arc1, arc2 = pc.radius[p1] > 0, pc.radius[p2] > 0
    # tcGetOverallMaxAccel: the kink share off, halved by the parabolic end condition; tangential: an
    # arc that is not finalized keeps BLEND_ACC_RATIO_TANGENTIAL
    overall1 = pc.a_max[p1] * (1.0 - kink_ratio) * 0.5
    overall2 = pc.a_max[p2] * (1.0 - kink_ratio) * 0.5
    acc1 = overall1 * np.where(arc1, BLEND_ACC_RATIO_TANGENTIAL, 1.0)
    acc2 = overall2 * np.where(arc2, BLEND_ACC_RATIO_TANGENTIAL, 1.0)
    len1, len2 = pc.length[p1], pc.length[p2]
    v1 = np.minimum(np.sqrt(acc1 * len1 / 2.0), v_target[p1])     # triangle speed over half the move
    v2 = np.minimum(np.sqrt(acc2 * len2 / 2.0), v_target[p2])
    with np.errstate(divide="ignore", invalid="ignore"):
        t_reach = np.minimum(len1 / v1, len2 / v2)
        t_blend = np.minimum(t_reach, np.maximum(v1 / acc1, v2 / acc2))
    b1 = np.minimum(v1, t_blend * acc1)
    b2 = np.minimum(v2, t_blend * acc2)
    # the next move's start acceleration direction: on an arc, the tangent at the overall acceleration
    # plus the normal acceleration of half the feed on its radius
    lin = list(lin)
    d2 = u2.copy()
    k = np.flatnonzero(arc2)
    if len(k):
        p = p2[k]
        inward = -pc.e1[p][:, lin]
        d2[k] = u2[k] * overall2[k, None] + inward * ((0.5 * feed[p]) ** 2 / pc.radius[p])[:, None]
        d2[k] /= np.sqrt(np.einsum("ij,ij->i", d2[k], d2[k]))[:, None]
    theta = np.arccos(np.clip(-np.einsum("ij,ij->i", u1, d2), -1.0, 1.0)) / 2.0
    cos_t = np.cos(theta)
    capped = (np.nan_to_num(tol) > 0) & (cos_t > math.cos(math.pi / 2 - MIN_ARC_ANGLE))
    with np.errstate(invalid="ignore"):
        v_tol = 2.0 * np.sqrt(acc1 * np.where(capped, tol, 0.0) / np.where(capped, cos_t, 1.0))
    b1 = np.where(capped, np.minimum(b1, v_tol), b1)
    b2 = np.where(capped, np.minimum(b2, v_tol), b2)
    v_net = np.sin(theta) * (b1 + b2) / 2.0
    return np.nan_to_num(v_net / 2.0)


def parabolic_chosen(pc, rated: np.ndarray, arc_rate: np.ndarray, kink_vel: np.ndarray, u1, u2, *,
                     feed: np.ndarray, v_seg: np.ndarray, tol: np.ndarray, kink_ratio: float, lin) -> np.ndarray:
    """Per junction, whether LinuxCNC takes a parabolic blend there: among the `rated` junctions (where it
    tries a blend arc), those whose parabolic rating is at least the blend arc's (`arc_rate`, 0 where none
    can be made) and the kink speed. `v_seg`: per piece, the feed capped by the axes and one servo cycle;
    an arc's target speed is further capped at the canon's centripetal speed."""
    jr = np.flatnonzero(rated)
    chosen = np.zeros(len(rated), bool)
    if not len(jr):
        return chosen
    arc_cap = np.sqrt(math.sqrt(1 - BLEND_ACC_RATIO_TANGENTIAL ** 2) * pc.a_max * pc.radius)
    v_target = np.where(pc.radius > 0, np.minimum(v_seg, arc_cap), v_seg)
    perf = parabolic_performance(pc, jr, u1[jr], u2[jr], feed=feed, v_target=v_target, tol=tol[jr],
                                 kink_ratio=kink_ratio, lin=lin)
    chosen[jr] = (perf > 0) & (perf >= arc_rate[jr]) & (perf >= kink_vel[jr])
    return chosen
