"""Chapter 6 environments: Gymnasium API, determinism, Eq. 6.6, obstacle placement and
the sphere test (RMP-VICES stops short of an obstacle VICES drives the arm into)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from artic.errors import InputError
from artic.sim.rmp_envs import RmpEnv, push_reward
from artic.sim.rmp_tasks import Box3, get_rmp_task


@pytest.mark.parametrize(
    ("task", "controller"), [("traj", "rmp_vices"), ("door", "rmp_vices"), ("push", "vices")]
)
def test_passes_gymnasium_check_env(task, controller):
    env = RmpEnv(task, controller, seed=0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env, skip_render_check=True)
    finally:
        env.close()


def _episode(task, controller, seed, steps=8, obstacles=False):
    env = RmpEnv(task, controller, obstacles=obstacles, seed=None)
    rng = np.random.default_rng(seed)
    try:
        obs, _ = env.reset(seed=seed)
        out = [obs.tobytes()]
        for _ in range(steps):
            obs, reward, terminated, _, _ = env.step(rng.uniform(-1, 1, 12).astype(np.float32))
            out += [obs.tobytes(), np.float64(reward).tobytes(), bytes([terminated])]
            if terminated:
                break
        return b"".join(out)
    finally:
        env.close()


@pytest.mark.parametrize("task", ["traj", "push"])
def test_same_seed_same_bytes(task):
    assert _episode(task, "rmp_vices", 3) == _episode(task, "rmp_vices", 3)
    assert _episode(task, "rmp_vices", 3) != _episode(task, "rmp_vices", 4)


def test_reset_after_an_episode_repeats_it():
    env = RmpEnv("traj", "vices", seed=0)
    try:
        first = env.reset(seed=5)[0]
        for _ in range(5):
            env.step(np.ones(12, dtype=np.float32))
        assert np.array_equal(env.reset(seed=5)[0], first)
    finally:
        env.close()


def test_push_reward_is_eq_6_6():
    assert push_reward(0.0, 0.0, 0.5, 2.0) == pytest.approx(2.5)
    assert push_reward(0.05, 0.1, 0.5, 2.0) == pytest.approx(
        0.5 * (1 - np.tanh(1.0)) + 2.0 * (1 - np.tanh(2.0))
    )
    assert push_reward(10.0, 10.0, 0.5, 2.0) == pytest.approx(0.0)
    # larger distances never pay more
    assert push_reward(0.02, 0.0, 1, 1) > push_reward(0.04, 0.0, 1, 1)


@pytest.mark.parametrize("task", ["traj", "door", "push"])
def test_obstacles_are_placed_in_their_volume_clear_of_the_task(task):
    env = RmpEnv(task, "rmp_vices", obstacles=True, seed=0)
    cfg = env.task.obstacles
    try:
        for seed in range(5):
            env.reset(seed=seed)
            centres = env.sphere_centres
            assert centres.shape == (cfg.count, 3)
            lo = np.subtract(cfg.volume.centre, cfg.volume.half_extents)
            hi = np.add(cfg.volume.centre, cfg.volume.half_extents)
            assert np.all((centres >= lo) & (centres <= hi))
            gap = np.linalg.norm(centres[0] - centres[1])
            assert gap >= 2 * cfg.radius
            for c in centres:
                if task == "traj":
                    assert np.all(np.linalg.norm(env.via_points - c, axis=1) >= cfg.radius)
                if task == "door":  # clear of the door's swing
                    swing = np.linalg.norm((c - env._hinge_point)[:2])
                    assert swing >= env.task.scene.width + cfg.radius
            # the RMPs see them
            spheres = [o for o in env.rmp_obstacles() if hasattr(o, "centre")]
            assert len(spheres) == cfg.count
    finally:
        env.close()


def test_the_door_opens_along_its_grasp_without_nearing_a_limit_and_its_spheres_are_on_the_way():
    """The door task's geometry (docs/rmp.md): holding the handle as at the start, the
    door turns to its goal angle with every joint outside the safety envelope's sigma1
    (0.3 rad) of its limits, and the evaluation spheres lie where that arm passes."""
    env = RmpEnv("door", "vices", obstacles=True, seed=0)
    try:
        path = env.grasp_path(np.linspace(0.0, env.task.scene.goal_angle, 11))
        assert path is not None
        low, high = env.limits
        assert np.minimum(path - low, high - path).min() > 0.3
        swept = []
        for q in path[1:]:
            env.robot.set_state(q)
            _, points = env.arm_state()
            assert points is not None
            swept.append((points.positions, points.radii))
        on_the_way = 0
        for seed in range(20):
            env.reset(seed=seed)
            reach = env.task.obstacles.radius
            on_the_way += any(
                np.any(np.linalg.norm(positions - c, axis=1) < radii + reach)
                for c in env.sphere_centres
                for positions, radii in swept
            )
        assert on_the_way >= 10
    finally:
        env.close()


def test_unplaceable_obstacles_are_bad_input():
    base = get_rmp_task("traj")
    tiny = Box3(centre=[0.55, 0.0, 0.45], half_extents=[0.0, 0.0, 0.0])  # one point
    task = base.model_copy(update={"obstacles": base.obstacles.model_copy(update={"volume": tiny})})
    env = RmpEnv(task, "vices", obstacles=True, seed=0)
    try:
        with pytest.raises(InputError, match="cannot be placed clear in 1000 draws"):
            env.reset(seed=0)
    finally:
        env.close()


def test_unknown_task_or_controller_is_bad_input():
    with pytest.raises(InputError, match="unknown RMP task"):
        RmpEnv("drawer", "vices")
    with pytest.raises(InputError, match="controller"):
        RmpEnv("traj", "osc")  # type: ignore[arg-type]


def test_arm_driven_through_a_sphere_rmp_vices_stays_clear_vices_hits():
    """The tool driven along +y at the default stiffness sweeps the forearm through a
    sphere: VICES collides within a second, RMP-VICES stays clear for 3 s."""
    base = get_rmp_task("traj")
    task = base.model_copy(update={"robot": base.robot.model_copy(update={"start_noise": 0.0})})
    action = np.zeros(12, dtype=np.float32)
    action[1] = 1.0
    sphere = np.array([[0.62, 0.28, 0.58]])
    collided = {}
    for controller in ("vices", "rmp_vices"):
        env = RmpEnv(task, controller, seed=0)
        try:
            env.reset(seed=0)
            env.place_spheres(sphere)
            collided[controller] = False
            for _ in range(60):
                _, _, terminated, _, info = env.step(action)
                if info["collision"]:
                    collided[controller] = True
                    assert info["contact_force"] > 0  # the impact's force, N (Fig. 6.4)
                if terminated:
                    break
        finally:
            env.close()
    assert collided == {"vices": True, "rmp_vices": False}


def test_rmp_vices_reduces_to_vices_on_the_iiwa_at_rest():
    """Section 6.3.2 on the simulated arm: no obstacles, joint-limit metric 0, at rest, the
    same tool acceleration J q'' (1e-6) at 20 random configurations."""
    from artic.control.osc import joint_acceleration, vices_command, vices_torque
    from artic.control.rmp import JointLimitRmpConfig, RmpConfig, rmp_vices_acceleration

    env = RmpEnv("traj", "rmp_vices", seed=0)
    cfg = RmpConfig(joint_limit=JointLimitRmpConfig(metric=0.0))
    rng = np.random.default_rng(0)
    low, high = env.limits
    try:
        for _ in range(20):
            env.robot.set_state(rng.uniform(low + 0.3, high - 0.3))
            state, points = env.arm_state()
            assert np.allclose(state.ee_jdot_qdot, 0.0)  # at rest
            cmd = vices_command(rng.uniform(-1, 1, 12), state.ee_position, state.ee_rotation,
                                env.vices_cfg)  # fmt: skip
            qdd_vices = joint_acceleration(state, vices_torque(state, cmd, env.start_q,
                                                               env.vices_cfg))  # fmt: skip
            qdd_rmp = rmp_vices_acceleration(state, cmd, env.start_q, env.limits, points, [],
                                             env.vices_cfg, cfg)  # fmt: skip
            J = state.ee_jacobian
            assert np.allclose(J @ qdd_rmp, J @ qdd_vices, atol=1e-6)
    finally:
        env.close()


def _random_episodes(task: str, controller: str, episodes: int) -> tuple[float, int]:
    """PPO's first epoch in small: Gaussian actions (s.d. 1, clipped), `episodes` episodes
    of 256 steps. Returns (the largest joint speed over its limit, joint-limit events)."""
    env = RmpEnv(task, controller)
    worst, events = 0.0, 0
    try:
        for episode in range(episodes):
            rng = np.random.default_rng(episode)
            env.reset(seed=episode)
            for _ in range(256):
                action = np.clip(rng.normal(0.0, 1.0, 12), -1.0, 1.0).astype(np.float32)
                _, _, terminated, _, info = env.step(action)
                speed = np.abs(env.robot.qd()) / env.robot.velocity_limits
                worst = max(worst, float(speed.max()))
                if terminated:
                    events += int(info["joint_limit"])
                    break
    finally:
        env.close()
    return worst, events


def test_joint_speeds_stay_near_the_iiwas_limits():
    """The wrist of the door's grasp under random VICES actions: PyBullet holds every
    joint near its datasheet speed (`cap_joint_speeds`; the grasp's constraint lets a
    step end up to 1.8x above, measured); without the cap 8-10x, past the limit."""
    worst, _ = _random_episodes("door", "vices", 3)
    assert worst < 2.5


def test_random_actions_reach_a_joint_limit_under_vices_not_under_rmp_vices():
    """traj, 3 episodes of random actions: VICES ends at a joint limit, the joint-limit
    leaves of RMP-VICES keep every joint outside the 0.1 rad margin (docs/rmp.md)."""
    assert _random_episodes("traj", "vices", 3)[1] >= 2
    assert _random_episodes("traj", "rmp_vices", 3)[1] == 0
