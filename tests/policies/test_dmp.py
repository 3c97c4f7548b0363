"""DMPs (Eq. 2.4-2.7): LWR fit, rollout, goal/tau semantics, round trips, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from artic.control.tracking import JointTracker
from artic.errors import InputError
from artic.policies.dmp import (
    DMPConfig,
    DMPFile,
    DMPParams,
    fit_dmp,
    rollout_dmp,
)

Y0 = np.array([0.0, 1.0, -0.5, 0.3])
GOAL = np.array([1.0, 0.5, 0.7, 0.3])  # the last joint does not move


def min_jerk(duration: float, dt: float, y0=Y0, goal=GOAL) -> tuple[np.ndarray, np.ndarray]:
    """A minimum-jerk demo: t (T,), y (T, J)."""
    t = np.arange(round(duration / dt) + 1) * dt
    s = t / duration
    return t, y0 + (goal - y0) * (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None]


def relative_rms(a: np.ndarray, b: np.ndarray, span: np.ndarray) -> np.ndarray:
    return np.sqrt(((a - b) ** 2).mean(axis=0)) / np.maximum(span, 1e-9)


def test_config_defaults_and_critical_damping():
    cfg = DMPConfig()
    assert cfg.n_basis == 32 and cfg.alpha_z == 25.0 and cfg.beta_z == 25.0 / 4
    assert DMPConfig(alpha_z=40.0).beta_z == 10.0
    assert DMPConfig(alpha_z=40.0, beta_z=3.0).beta_z == 3.0
    c = cfg.centres()
    assert c.shape == (32,) and c[0] == 1.0 and np.isclose(c[-1], np.exp(-cfg.alpha_x))
    # evenly spaced in time: log c is linear in the index
    assert np.allclose(np.diff(np.log(c)), -cfg.alpha_x / 31)
    assert (cfg.widths() > 0).all()
    with pytest.raises(ValueError):
        DMPConfig(n_basis=1)


def test_fit_reproduces_a_min_jerk_demo_and_converges_to_the_goal():
    cfg = DMPConfig()
    t, y = min_jerk(2.0, 0.02)
    params = fit_dmp(t, y, cfg)
    assert params.weights_.shape == (4, 32)
    assert np.array_equal(params.y0, Y0) and np.allclose(params.goal, GOAL)
    assert params.tau == pytest.approx(2.0)
    traj = rollout_dmp(params, cfg, 0.02, len(t))
    assert traj.y.shape == traj.yd.shape == traj.ydd.shape == y.shape
    assert np.allclose(traj.t, t)
    span = np.ptp(y[:, :3], axis=0)
    assert (relative_rms(traj.y[:, :3], y[:, :3], span) < 0.01).all()
    assert np.abs(traj.y[:, 3] - 0.3).max() < 1e-9  # a joint at rest stays at rest
    # after the movement the transformation system settles at the goal
    long = rollout_dmp(params, cfg, 0.02, 3 * len(t))
    assert np.abs(long.y[-1] - GOAL).max() < 1e-3
    assert np.abs(long.yd[-1]).max() < 1e-2


def test_wiggly_demo_and_velocities_are_reproduced():
    cfg = DMPConfig()
    t, y = min_jerk(1.5, 0.01)
    y = y + 0.2 * (np.sin(np.pi * t / 1.5) ** 2 * np.sin(4 * t))[:, None]
    params = fit_dmp(t, y, cfg)
    traj = rollout_dmp(params, cfg, 0.01, len(t))
    assert (relative_rms(traj.y[:, :3], y[:, :3], np.ptp(y[:, :3], axis=0)) < 0.01).all()
    yd = np.gradient(y, t, axis=0)
    assert (relative_rms(traj.yd, yd, np.ptp(yd, axis=0)) < 0.05).all()


def test_tau_scales_time():
    cfg = DMPConfig()
    t, y = min_jerk(1.0, 0.01)
    p = fit_dmp(t, y, cfg)
    slow = DMPParams(p.weights_, p.y0, p.goal, 2 * p.tau)
    a = rollout_dmp(p, cfg, 0.01, 100)
    # exactly: only dt / tau enters the integration
    b = rollout_dmp(slow, cfg, 0.02, 100)
    assert np.array_equal(a.y, b.y)
    assert np.allclose(b.yd, a.yd / 2, rtol=0, atol=1e-12)
    assert np.allclose(b.ydd, a.ydd / 4, rtol=0, atol=1e-9)
    # at the same dt the slow DMP is the same path at half the speed: y_slow(2t) ~ y(t)
    c = rollout_dmp(slow, cfg, 0.005, 400)
    assert np.abs(c.y[::2][:200:2] - a.y[:100]).max() < 0.02


def test_goal_change_adds_the_spring_damper_step_response():
    cfg = DMPConfig()
    t, y = min_jerk(1.0, 0.01)
    p = fit_dmp(t, y, cfg)
    delta = np.array([0.2, -0.1, 0.05, 0.3])
    moved = DMPParams(p.weights_, p.y0, p.goal + delta, p.tau)
    a = rollout_dmp(p, cfg, 0.01, 300)
    b = rollout_dmp(moved, cfg, 0.01, 300)
    # Eq. 2.4-2.5 are linear in (y, z, g): the difference is the response of the
    # unforced system to a goal step, (1 - (1 + w t) e^{-w t}) delta with w = alpha_z/(2 tau)
    zero = DMPParams(np.zeros_like(p.weights_), np.zeros(4), delta, p.tau)
    step = rollout_dmp(zero, cfg, 0.01, 300)
    assert np.allclose(b.y - a.y, step.y, atol=1e-12)
    w = cfg.alpha_z / (2 * p.tau)
    analytic = (1 - (1 + w * a.t) * np.exp(-w * a.t))[:, None] * delta
    assert np.abs(step.y - analytic).max() < 0.02 * np.abs(delta).max()
    assert np.allclose(b.y[-1], p.goal + delta, atol=1e-3)


def test_multi_demo_fit_pools_demos_of_different_durations():
    cfg = DMPConfig()
    demos = [min_jerk(d, 0.01) for d in (0.8, 1.0, 1.2)]
    params = fit_dmp([d[0] for d in demos], [d[1] for d in demos], cfg)
    assert params.tau == pytest.approx(1.0)
    single = fit_dmp(*demos[1], cfg)
    # the same shape mapped to phase: pooled weights agree with the single fit
    assert np.allclose(params.weights_, single.weights_, rtol=0.05, atol=0.5)
    traj = rollout_dmp(params, cfg, 0.01, len(demos[1][0]))
    span = np.ptp(demos[1][1][:, :3], axis=0)
    assert (relative_rms(traj.y[:, :3], demos[1][1][:, :3], span) < 0.01).all()
    # different starts and goals: y0 and goal are the demos' means
    t, y2 = min_jerk(1.0, 0.01, Y0 + 0.1, GOAL - 0.1)
    both = fit_dmp([t, t], [demos[1][1], y2], cfg)
    assert np.allclose(both.y0, Y0 + 0.05) and np.allclose(both.goal, GOAL - 0.05)


def test_json_round_trip_is_exact():
    t, y = min_jerk(1.0, 0.01)
    p = fit_dmp(t, y + 1e-3 * np.sin(7 * t)[:, None], DMPConfig(n_basis=10))
    q = DMPParams.from_json_dict(json.loads(json.dumps(p.to_json_dict())))
    assert np.array_equal(p.weights_, q.weights_) and np.array_equal(p.goal, q.goal)
    assert np.array_equal(p.y0, q.y0) and p.tau == q.tau
    bad = p.to_json_dict() | {"n_basis": 11}
    with pytest.raises(InputError, match="n_basis"):
        DMPParams.from_json_dict(bad)
    with pytest.raises(InputError, match="malformed"):
        DMPParams.from_json_dict({"weights": [[1.0]], "y0": [0.0]})


def test_dmp_file_round_trip_keeps_gains_and_params():
    cfg = DMPConfig(n_basis=8, alpha_z=30.0, alpha_x=3.0, integration_substeps=2)
    t, y = min_jerk(1.0, 0.05)
    record = DMPFile("drawer", 0.05, fit_dmp(t, y, cfg), cfg)
    data = json.loads(json.dumps(record.to_json_dict()))
    assert data["beta_z"] == 7.5 and data["n_joints"] == 4 and data["dt"] == 0.05
    back = DMPFile.from_json_dict(data | {"demos_used": ["demo_000.npz"]})
    assert back.cfg == cfg and back.task == "drawer" and back.dt == 0.05
    assert np.array_equal(back.params.to_vector(), record.params.to_vector())
    with pytest.raises(InputError, match="n_basis"):
        DMPFile.from_json_dict(data | {"n_basis": 9})
    with pytest.raises(InputError, match="dt"):
        DMPFile.from_json_dict({k: v for k, v in data.items() if k != "dt"})


def test_vector_round_trip_and_layout():
    t, y = min_jerk(1.0, 0.01)
    p = fit_dmp(t, y, DMPConfig(n_basis=10))
    v = p.to_vector()
    lay = p.layout
    assert v.shape == (lay.size,) == (4 * 10 + 4 + 1,)
    q = p.from_vector(v)
    assert np.array_equal(q.to_vector(), v) and np.array_equal(q.y0, p.y0)
    assert np.array_equal(v[lay.weights], p.weights_.ravel())
    assert np.array_equal(v[lay.goal], p.goal) and v[lay.tau][0] == p.tau
    masks = [lay.mask(b) for b in ("weights", "goal", "tau")]
    assert (sum(m.astype(int) for m in masks) == 1).all()
    labels = lay.labels()
    assert len(labels) == lay.size and labels[-1] == "tau" and labels[lay.goal][0] == "goal[0]"
    assert labels[11] == "w[1,1]"
    w = v.copy()
    w[lay.tau] = -1.0
    with pytest.raises(InputError, match="tau"):
        p.from_vector(w)
    assert p.from_vector(w, tau_min=0.1).tau == 0.1
    with pytest.raises(InputError, match="shape"):
        p.from_vector(v[:-1])
    with pytest.raises(InputError, match="block"):
        lay.mask("speed")


def test_controller_tracks_the_rollout_with_feedback():
    cfg = DMPConfig()
    t, y = min_jerk(1.0, 0.02)
    p = fit_dmp(t, y, cfg)
    traj = rollout_dmp(p, cfg, 0.02, 50)
    ctrl = JointTracker(traj.y, traj.yd, k_p=10.0)
    assert np.allclose(ctrl.action(3, traj.y[3]), traj.yd[3])
    q = traj.y[3] + 0.1
    assert np.allclose(ctrl.action(3, q), traj.yd[3] - 1.0)
    # beyond the rollout: hold the last point
    assert np.allclose(ctrl.action(80, traj.y[-1]), 0.0)
    obs = np.concatenate([traj.y[5], [0.7]])  # [q_R, q_O]
    assert np.array_equal(ctrl(obs, 5), ctrl.action(5, traj.y[5]))
    # integrating the actions (a perfect velocity-controlled robot) follows the DMP
    qr = p.y0.copy()
    for k in range(50):
        qr = qr + 0.02 * ctrl.action(k, qr)
    assert np.abs(qr - traj.y[-1]).max() < 0.02
    with pytest.raises(InputError, match="q_robot"):
        ctrl.action(0, np.zeros(3))
    with pytest.raises(InputError, match="k_p"):
        JointTracker(traj.y, traj.yd, k_p=-1.0)


@pytest.mark.parametrize(
    ("t", "y", "match"),
    [
        (np.linspace(0, 1, 10), np.zeros((9, 7)), "samples"),
        (np.linspace(0, 1, 10), np.full((10, 7), np.nan), "finite"),
        (np.array([0.0]), np.zeros((1, 7)), "at least 2"),
        (np.array([0.0, 0.5, 0.5, 1.0]), np.zeros((4, 7)), "increasing"),
        (np.linspace(0, 1, 10), np.zeros((10, 7, 1)), "expected"),
    ],
)
def test_bad_demos_raise_input_error(t, y, match):
    with pytest.raises(InputError, match=match):
        fit_dmp(t, y)


def test_bad_multi_demo_and_rollout_input_raise():
    t, y = min_jerk(1.0, 0.1)
    with pytest.raises(InputError, match="demo 1: has 3 joints"):
        fit_dmp([t, t], [y, y[:, :3]])
    with pytest.raises(InputError, match="no demonstrations"):
        fit_dmp([], [])
    with pytest.raises(InputError, match="lists of equal length"):
        fit_dmp([t, t], [y])
    p = fit_dmp(t, y)
    with pytest.raises(InputError, match="basis"):
        rollout_dmp(p, DMPConfig(n_basis=10), 0.1, 10)
    with pytest.raises(InputError, match="dt"):
        rollout_dmp(p, DMPConfig(), 0.0, 10)
    with pytest.raises(InputError, match="tau"):
        DMPParams(p.weights_, p.y0, p.goal, 0.0)
    with pytest.raises(InputError, match="y0"):
        DMPParams(p.weights_, p.y0[:2], p.goal, 1.0)
