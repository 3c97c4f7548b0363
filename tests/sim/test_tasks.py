"""Task configurations and their registry (Chapter 5, section 5.3.1)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from pydantic import ValidationError

from artic.errors import InputError
from artic.objects.categories import build
from artic.objects.spec import CategoryConfig
from artic.sim.tasks import (
    TASKS,
    ArticulatedScene,
    GraspConfig,
    TaskConfig,
    TBallScene,
    get_task,
    register_task,
)

CONF = Path(__file__).resolve().parents[2] / "conf" / "common"
NAMES = ("drawer", "microwave", "tball")


def test_the_three_tasks_are_registered():
    assert set(NAMES) <= set(TASKS)
    for name in NAMES:
        task = get_task(name)
        assert isinstance(task, TaskConfig) and task.name == name


def test_unknown_task_is_an_input_error_listing_the_known_ones():
    with pytest.raises(InputError) as err:
        get_task("dishwasher")
    message = str(err.value)
    assert "dishwasher" in message and all(name in message for name in NAMES)
    assert "\n" not in message


@pytest.mark.parametrize("name", NAMES)
def test_yaml_mirrors_the_registered_defaults(name):
    data = yaml.safe_load((CONF / "task" / f"{name}.yaml").read_text())
    assert TaskConfig.model_validate(data) == get_task(name)


@pytest.mark.parametrize("name", NAMES)
def test_reward_and_rates_follow_the_thesis_and_the_speed_budget(name):
    task = get_task(name)
    assert task.reward.c == 60.0 and task.reward.r == 0.001  # Eq. 5.1
    assert math.isclose(task.physics_dt, 1.0 / 240.0)
    assert 1.0 <= task.horizon * task.control_dt <= 6.0  # a few seconds
    assert len(task.goal) == len(task.object_start) == 1
    assert len(task.robot.start_q) == 7


@pytest.mark.parametrize("name", ["drawer", "microwave"])
def test_object_geometry_is_inside_appendix_a_and_builds(name):
    scene = get_task(name).scene
    assert isinstance(scene, ArticulatedScene)
    ranges = CategoryConfig.model_validate(
        yaml.safe_load((CONF / "category" / f"{name}.yaml").read_text())
    )
    for value, (lo, hi) in (
        (scene.depth, ranges.geometry.depth),
        (scene.width, ranges.geometry.width),
        (scene.height, ranges.geometry.height),
    ):
        assert lo <= value <= hi
    lo, hi = scene.joint_limits
    assert ranges.configuration[0] <= lo < hi <= ranges.configuration[1] + 1e-12
    obj = build(scene.spec())
    assert obj.dof == 1 and obj.links[0].role == "body" and obj.links[2].role == "handle"
    assert obj.movable_joints[0].damping == scene.parts.joint_damping


def test_goals_lie_inside_the_object_ranges():
    drawer, microwave = get_task("drawer"), get_task("microwave")
    assert isinstance(drawer.scene, ArticulatedScene)
    assert drawer.object_start == [0.0]  # starts closed
    assert 0.5 * drawer.scene.joint_limits[1] < drawer.goal[0] <= drawer.scene.joint_limits[1]
    assert microwave.goal == [0.0] and microwave.object_start[0] > 1.0  # open -> shut
    assert not microwave.grasp.enabled and drawer.grasp.enabled
    assert isinstance(get_task("tball").scene, TBallScene)


def test_invalid_configs_are_rejected():
    with pytest.raises(ValidationError):
        TaskConfig(goal=[0.1, 0.2], object_start=[0.0])
    with pytest.raises(ValidationError):
        GraspConfig(attach_distance=0.05, slip_distance=0.04)
    with pytest.raises(ValidationError):
        TaskConfig.model_validate({"scene": {"kind": "teapot"}})
    with pytest.raises(ValidationError):
        TaskConfig.model_validate({"horizon": 0})


def test_registering_a_name_twice_fails():
    with pytest.raises(ValueError, match="already registered"):
        register_task("drawer")(lambda: TaskConfig())


def test_configs_round_trip_through_json():
    for name in NAMES:
        task = get_task(name)
        assert TaskConfig.model_validate_json(task.model_dump_json()) == task
