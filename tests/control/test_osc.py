"""VICES (Eq. 6.1): the orientation error, the action scaling and the critically
damped impedance."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from artic.control.osc import (
    VicesConfig,
    axis_angle_matrix,
    orientation_error,
    stiffness,
    vices_command,
)


def test_orientation_error_is_zero_at_the_goal_and_sin_theta_u_off_it():
    rng = np.random.default_rng(0)
    for _ in range(20):
        rotation = axis_angle_matrix(rng.normal(size=3))
        assert np.allclose(orientation_error(rotation, rotation), 0.0, atol=1e-12)
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        theta = rng.uniform(-np.pi, np.pi)
        goal = axis_angle_matrix(theta * u) @ rotation
        assert np.allclose(orientation_error(rotation, goal), np.sin(theta) * u, atol=1e-12)


def test_action_scaling_bounds_the_goal_and_the_stiffness():
    cfg = VicesConfig()
    rng = np.random.default_rng(1)
    position, rotation = np.array([0.5, 0.0, 0.5]), np.eye(3)
    for _ in range(50):
        action = rng.uniform(-3, 3, size=12)  # clipped to [-1, 1]
        cmd = vices_command(action, position, rotation, cfg)
        assert np.linalg.norm(cmd.goal_position - position) <= cfg.position_scale + 1e-12
        angle = np.arccos(np.clip((np.trace(cmd.goal_rotation) - 1) / 2, -1, 1))
        assert angle <= cfg.rotation_scale + 1e-9
        for kp in (cmd.kp_pos, cmd.kp_ori):
            assert np.all((kp >= cfg.kp_min) & (kp <= cfg.kp_max))
        assert np.allclose(cmd.kd_pos, 2 * np.sqrt(cmd.kp_pos))
    assert np.allclose(stiffness(np.array([-1.0, 1.0]), cfg), [cfg.kp_min, cfg.kp_max])


def test_kp_min_above_kp_max_is_refused():
    with pytest.raises(ValidationError, match="kp_min"):
        VicesConfig(kp_min=300.0, kp_max=10.0)


@pytest.mark.parametrize("kp", [10.0, 100.0, 300.0])
def test_step_response_at_critical_damping_overshoots_less_than_one_percent(kp):
    """A unit mass under a = k_p (x_g - x) - 2 sqrt(k_p) x' (the decoupled axis VICES
    commands): a 1 m step, integrated finely, overshoots < 1%."""
    kd = 2 * np.sqrt(kp)
    x, v, dt = 0.0, 0.0, 1e-4
    peak = 0.0
    for _ in range(int(10 / np.sqrt(kp) / dt) + 1):
        a = kp * (1.0 - x) - kd * v
        v += a * dt
        x += v * dt
        peak = max(peak, x)
    assert peak < 1.01
    assert abs(x - 1.0) < 1e-2
