"""The heavy drawer of issue 23 (`task=drawer`) and the light one kept as `drawer_light`:
the runners' breakaway force, and a grasped pull at the planned speed that slips while a
slower one opens the drawer (thesis Fig. 5.3b)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from artic.sim.tasks import (
    HEAVY_DRAWER_DAMPING,
    HEAVY_DRAWER_FRICTION,
    TaskConfig,
    get_task,
)
from artic.sim.world import TaskWorld

CONF = Path(__file__).resolve().parents[2] / "conf" / "common" / "task"


@pytest.fixture(scope="module")
def heavy():
    with TaskWorld.create(get_task("drawer")) as world:
        yield world


def pull_with_constant_force(world: TaskWorld, force: float, seconds: float = 1.0) -> float:
    """Pull the closed drawer's moving part towards the robot (world -x, its opening
    direction) with a constant force (N) at its centre of mass; returns the opening, m."""
    world.reset(np.asarray(world.cfg.robot.start_q), np.zeros(1))
    client, body, joint = world._sim_client, world._sim.target, world._object_joints[0]
    for _ in range(round(seconds / world.cfg.physics_dt)):
        centre = client.getLinkState(body, joint)[0]
        client.applyExternalForce(body, joint, [-force, 0.0, 0.0], centre, client.WORLD_FRAME)
        client.stepSimulation()
    return float(world.object_q()[0])


def test_the_heavy_drawer_is_a_loaded_drawer_on_stiff_runners():
    parts = get_task("drawer").scene.parts
    assert parts.joint_friction == HEAVY_DRAWER_FRICTION == 100.0
    assert parts.joint_damping == HEAVY_DRAWER_DAMPING == 300.0
    grasp = get_task("drawer").grasp
    planned_speed = 0.25  # plan-demos' timing.object_max_velocity, m/s
    # the planned pull needs more than the grasp transmits; a standing pull does not
    needed = parts.joint_friction + planned_speed * parts.joint_damping
    assert parts.joint_friction < grasp.max_force < needed


def test_light_drawer_is_the_same_task_with_light_runners():
    heavy, light = get_task("drawer"), get_task("drawer_light")
    assert light.name == "drawer_light"
    assert light.scene.parts.joint_friction == 15.0 and light.scene.parts.joint_damping == 20.0
    same_parts = light.scene.parts.model_copy(
        update={"joint_friction": HEAVY_DRAWER_FRICTION, "joint_damping": HEAVY_DRAWER_DAMPING}
    )
    same = light.model_copy(
        update={"name": "drawer", "scene": light.scene.model_copy(update={"parts": same_parts})}
    )
    assert same == heavy


@pytest.mark.parametrize("name", ["drawer", "drawer_light"])
def test_yaml_mirrors_the_registered_drawer(name):
    data = yaml.safe_load((CONF / f"{name}.yaml").read_text())
    assert TaskConfig.model_validate(data) == get_task(name)


@pytest.mark.parametrize("fraction", [0.0, 0.5, 0.9])
def test_a_constant_pull_below_the_breakaway_force_does_not_move_it(heavy, fraction):
    assert abs(pull_with_constant_force(heavy, fraction * HEAVY_DRAWER_FRICTION)) < 1e-6


@pytest.mark.parametrize("fraction", [1.1, 1.4])
def test_a_constant_pull_above_the_breakaway_force_opens_it(heavy, fraction):
    force = fraction * HEAVY_DRAWER_FRICTION
    opening = pull_with_constant_force(heavy, force)
    assert opening > 0.01
    # viscous runners: after a second it moves at about (F - F_c) / b, never faster
    terminal_speed = (force - HEAVY_DRAWER_FRICTION) / HEAVY_DRAWER_DAMPING
    assert 0.5 * terminal_speed < opening <= terminal_speed


def test_the_light_drawer_gives_way_to_a_small_pull():
    with TaskWorld.create(get_task("drawer_light")) as light:
        assert pull_with_constant_force(light, 0.5 * HEAVY_DRAWER_FRICTION) > 0.05


# -- a grasped pull: the planned speed slips, a slower pull opens it ---------------------


def frame(direction, position) -> np.ndarray:
    """(4, 4) tool pose whose z axis (approach) is `direction`, at `position`."""
    d = np.asarray(direction, dtype=np.float64) / np.linalg.norm(direction)
    y = np.cross(d, [0.0, 0.0, 1.0])
    y /= np.linalg.norm(y)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([np.cross(y, d), y, d], axis=1)
    pose[:3, 3] = position
    return pose


def grasp_and_pull(world: TaskWorld, speed: float, distance: float = 0.25) -> float:
    """Reach the handle, then pull it straight back at `speed` (m/s) by `distance` and
    hold for 10 steps (tool poses tracked by IK, one per control step); returns the
    drawer's opening, m."""
    world.reset(np.asarray(world.cfg.robot.start_q), np.zeros(1))
    model = world.kinematic_model()
    pose = model.link_poses(np.zeros(1))[world.grasp_target_link]
    handle = (pose @ np.append(world.grasp_point, 1.0))[:3]
    tool0 = world.ee_pose()[:3, 3]
    approach = [tool0 + (handle - tool0) * min(1.0, (k + 1) / 12) for k in range(16)]
    steps = int(np.ceil(distance / (speed * world.dt)))
    pull = [handle - [min(distance, speed * world.dt * (k + 1)), 0.0, 0.0] for k in range(steps)]
    for k, target in enumerate([*approach, *pull, *[pull[-1]] * 10]):
        q = world.robot_q()
        goal = world.ik(frame([1, 0, 0], target), q)
        world.apply_action(np.zeros(7) if goal is None else (goal - q) / world.dt)
        world.step()
        if k == len(approach) - 1:
            assert world.grasp_held
    return float(world.object_q()[0])


def test_a_pull_at_the_planned_speed_slips_and_a_slower_one_opens_it(heavy):
    threshold = heavy.cfg.success_threshold
    fast = grasp_and_pull(heavy, speed=0.25)
    assert not heavy.grasp_held and fast < heavy.cfg.goal[0] - threshold
    slow = grasp_and_pull(heavy, speed=0.1)
    assert heavy.grasp_held and abs(slow - heavy.cfg.goal[0]) <= threshold
