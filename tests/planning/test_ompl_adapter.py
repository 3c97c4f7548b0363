"""The OMPL adapter on toy configuration spaces (no simulator)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from artic.planning.ompl_adapter import Planner, densify, ompl_seed, plan_path

LOW, HIGH = np.zeros(2), np.ones(2)
START, GOAL = np.array([0.1, 0.1]), np.array([0.9, 0.9])


def maze_valid(q: np.ndarray) -> bool:
    """Two walls: x ~ 0.33 open only at the top, x ~ 0.66 open only at the bottom."""
    x, y = q
    if 0.30 < x < 0.36 and y < 0.8:
        return False
    return not (0.63 < x < 0.69 and y > 0.2)


def boxed_goal_valid(q: np.ndarray) -> bool:
    """A closed square wall around the goal: the goal is valid but unreachable."""
    inside = np.all(np.abs(q - GOAL) < 0.08)
    ring = np.all(np.abs(q - GOAL) < 0.06)
    return not (inside and not ring)


@pytest.mark.parametrize("planner", ["rrtconnect", "rrtstar"])
def test_solves_the_maze_with_valid_finely_spaced_states(planner: Planner) -> None:
    res = plan_path(
        LOW, HIGH, START, GOAL, maze_valid, planner, 2.0, seed=1, resolution=0.01, max_checks=20_000
    )
    assert res.solved and res.status == "Exact solution"
    assert res.path.ndim == 2 and res.path.shape[1] == 2 and len(res.path) > 2
    np.testing.assert_array_equal(res.path[0], START)
    np.testing.assert_array_equal(res.path[-1], GOAL)
    assert all(maze_valid(q) for q in res.path)
    assert np.all(res.path >= LOW) and np.all(res.path <= HIGH)
    steps = np.linalg.norm(np.diff(res.path, axis=0), axis=1)
    assert steps.max() <= 0.01 + 1e-12
    # the walls force a detour: through the top gap of the first wall, the bottom of the second
    assert res.path[:, 1].max() > 0.8 and res.path[:, 1].min() < 0.2
    assert res.validity_checks > 0 and res.planning_time_s > 0


def test_same_seed_same_path_whatever_ran_before() -> None:
    first = plan_path(LOW, HIGH, START, GOAL, maze_valid, seed=3)
    others = [plan_path(LOW, HIGH, START, GOAL, maze_valid, seed=s) for s in (4, 5, 6)]
    again = plan_path(LOW, HIGH, START, GOAL, maze_valid, seed=3)
    np.testing.assert_array_equal(first.path, again.path)
    assert any(
        o.path.shape != first.path.shape or not np.array_equal(o.path, first.path) for o in others
    )


def test_rrtstar_with_a_check_budget_is_reproducible() -> None:
    runs = [
        plan_path(LOW, HIGH, START, GOAL, maze_valid, "rrtstar", 5.0, seed=2, max_checks=8000)
        for _ in range(2)
    ]
    assert runs[0].solved
    np.testing.assert_array_equal(runs[0].path, runs[1].path)


def test_unreachable_goal_is_not_solved_within_the_budget() -> None:
    res = plan_path(LOW, HIGH, START, GOAL, boxed_goal_valid, time_budget_s=0.3, seed=0)
    assert not res.solved and res.path.shape == (0, 2)
    assert res.planning_time_s < 0.3 + 1.0


def test_invalid_or_out_of_bounds_endpoints_fail_at_once() -> None:
    res = plan_path(LOW, HIGH, START, np.array([0.33, 0.5]), maze_valid, time_budget_s=5.0)
    assert not res.solved and res.status == "invalid goal" and res.planning_time_s < 1.0
    res = plan_path(LOW, HIGH, np.array([1.5, 0.5]), GOAL, maze_valid)
    assert not res.solved and res.status == "start outside bounds"


def test_one_dimensional_space() -> None:
    res = plan_path([0.0], [1.0], [0.0], [0.7], lambda q: True, resolution=0.1)
    assert res.solved
    np.testing.assert_allclose(res.path.ravel(), np.linspace(0.0, 0.7, 8), atol=1e-12)


def test_bad_arguments_raise() -> None:
    with pytest.raises(ValueError, match="shape"):
        plan_path([0.0, 0.0], [1.0], [0.0], [1.0], lambda q: True)
    with pytest.raises(ValueError, match="upper bound"):
        plan_path([0.0], [0.0], [0.0], [0.0], lambda q: True)
    with pytest.raises(ValueError, match="planner"):
        plan_path([0.0], [1.0], [0.0], [1.0], lambda q: True, planner="prm")  # type: ignore[arg-type]


def test_errors_in_the_validity_function_propagate() -> None:
    calls = []

    def broken(q: np.ndarray) -> bool:
        calls.append(q)
        if len(calls) > 2:  # the endpoints pass, the search fails
            raise RuntimeError("collision checker crashed")
        return True

    with pytest.raises(RuntimeError, match="crashed"):
        plan_path(LOW, HIGH, START, GOAL, broken)


def test_densify_and_seed_mapping() -> None:
    path = densify(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.25]]), 0.3)
    assert len(path) == 1 + 4 + 1
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() <= 0.3
    assert ompl_seed(0) > 0 and ompl_seed(2**31 - 2) > 0 and ompl_seed(5) != ompl_seed(6)


def test_no_leaked_ompl_instances_at_exit() -> None:
    script = textwrap.dedent(
        """
        import numpy as np
        from artic.planning.ompl_adapter import plan_path
        wall = lambda q: q[0] < 0.4 or q[0] > 0.6 or q[1] > 0.5
        res = plan_path([0, 0], [1, 1], [0.1, 0.1], [0.9, 0.9], wall)
        assert res.solved
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "leaked" not in out.stderr
