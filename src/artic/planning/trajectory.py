"""Time-parameterisation of a planned path into a trajectory at a fixed control period."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray


class Timed(NamedTuple):
    """A trajectory sampled every `dt` seconds.

    t: (T,) seconds from 0, step dt. q: (T, D) joint positions. qd: (T, D) the velocity
    to hold over [t_k, t_k + dt] to reach q[k + 1] (forward differences; 0 on the last
    step). extra: (T, E) quantities that move with the path (e.g. the object's
    configuration), interpolated at the same path parameter.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    extra: NDArray[np.float64]


def time_parameterize(
    waypoints: NDArray[np.float64],
    dt: float,
    max_velocity: ArrayLike,
    extra: ArrayLike | None = None,
    extra_max_velocity: ArrayLike | None = None,
    smoothing_s: float = 0.0,
    hold_s: float = 0.0,
) -> Timed:
    """Sample a piecewise-linear path at period `dt` within velocity limits.

    waypoints: (K, D) positions (rad or m). Each segment is traversed at constant
    velocity and takes the least time that keeps every |dq_j / dt| <= max_velocity[j]
    (D,), and the same for `extra` (K, E) against `extra_max_velocity` (E,). The
    positions are then smoothed by a Gaussian of standard deviation `smoothing_s`
    seconds (a normalised positive kernel: velocity limits and box joint limits still
    hold, corners are rounded). With smoothing the start is held for 4 standard
    deviations first (so the trajectory starts at rest at the start), and at least
    `hold_s` (with smoothing, at least 4 standard deviations) seconds of standing still
    end it, so it comes to rest at the path's end.
    """
    w = np.asarray(waypoints, dtype=np.float64)
    k, d = w.shape
    e = np.zeros((k, 0)) if extra is None else np.asarray(extra, dtype=np.float64).reshape(k, -1)
    vmax = np.broadcast_to(np.asarray(max_velocity, dtype=np.float64), (d,))
    if dt <= 0 or np.any(vmax <= 0):
        raise ValueError("dt and max_velocity must be positive")
    durations = np.max(np.abs(np.diff(w, axis=0)) / vmax, axis=1) if k > 1 else np.zeros(0)
    if e.shape[1] and extra_max_velocity is not None and k > 1:
        evmax = np.broadcast_to(np.asarray(extra_max_velocity, dtype=np.float64), (e.shape[1],))
        durations = np.maximum(durations, np.max(np.abs(np.diff(e, axis=0)) / evmax, axis=1))
    # zero-length segments (repeated waypoints) take no time: keep the later one only
    keep = np.concatenate([[True], durations > 0])
    w, e, durations = w[keep], e[keep], durations[durations > 0]
    knots = np.concatenate([[0.0], np.cumsum(durations)])
    hold = max(hold_s, 4.0 * smoothing_s)
    lead = math.ceil(round(4.0 * smoothing_s / dt, 9))
    moving = math.ceil(round(knots[-1] / dt, 9))
    steps = lead + moving + 1 + math.ceil(round(hold / dt, 9))
    t = np.arange(steps) * dt
    # the end time rounds up to a whole step: stretch the path slightly (never faster)
    scale = knots[-1] / (moving * dt) if moving > 0 else 1.0
    s = np.clip((t - lead * dt) * scale, 0.0, knots[-1])
    q, ex = _interp(s, knots, w), _interp(s, knots, e)
    if smoothing_s > 0 and len(t) > 2:
        q, ex = _smooth(q, smoothing_s / dt), _smooth(ex, smoothing_s / dt)
    qd = np.zeros_like(q)
    qd[:-1] = np.diff(q, axis=0) / dt
    return Timed(t, q, qd, ex)


def _interp(
    s: NDArray[np.float64], knots: NDArray[np.float64], values: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(len(s), C) column-wise linear interpolation of `values` (K, C) at `s`."""
    out = np.empty((len(s), values.shape[1]))
    for j in range(values.shape[1]):
        out[:, j] = np.interp(s, knots, values[:, j])
    return out


def _smooth(x: NDArray[np.float64], sigma_steps: float) -> NDArray[np.float64]:
    """Gaussian filter along time, edges held (scipy.ndimage, mode "nearest")."""
    if x.shape[1] == 0:
        return x
    from scipy.ndimage import gaussian_filter1d

    return np.asarray(gaussian_filter1d(x, sigma_steps, axis=0, mode="nearest"))
