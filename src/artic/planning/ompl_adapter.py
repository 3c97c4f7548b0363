"""Geometric motion planning in a box-bounded configuration space with OMPL 2.

`plan_path` is the MotionPlanner of Algorithm 2 (thesis, Chapter 5): it plans in any
R^D configuration space (the object's C_O, the robot's C_R) given only a validity
function, so it never sees a simulator ("planners take functions").

Determinism. OMPL draws every random number from RNG instances whose seeds come from one
process-wide seed generator, which `ompl.util.RNG.setSeed` seeds; OMPL warns that seeding
it again "will not lead to deterministic sampling" because RNG instances that already
exist keep their state. `plan_path` builds a fresh state space, planner and path
simplifier on every call, so all the RNG instances it uses are created after it
(re-)seeds the generator from `seed` (with OMPL's log silenced, so the warning about
re-seeding does not appear). Hence a call returns the same path for the
same arguments whatever ran before it in the process, provided the planner stops for a
reason that does not depend on the clock:
- "rrtconnect" stops when it connects the trees: reproducible unless it runs out of
  `time_budget_s` first;
- "rrtstar" is anytime and refines its path until told to stop: reproducible only with
  `max_checks` (stop after that many validity checks) reached before the time budget.
Planning is single-threaded; the validity function is called from the calling thread.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

Planner = Literal["rrtconnect", "rrtstar"]
PLANNERS: tuple[str, ...] = ("rrtconnect", "rrtstar")


@dataclass(frozen=True)
class PlanResult:
    """Outcome of `plan_path`.

    path: (K, D) float64 configurations from start to goal, consecutive ones at most
    `resolution` apart (Euclidean, configuration-space units); (0, D) when not solved.
    solved: an exact solution was found. status: OMPL's planner status ("Exact solution",
    "Timeout", "Invalid goal", ...). planning_time_s: wall time of the whole call.
    validity_checks: calls of the validity function.
    """

    path: NDArray[np.float64]
    solved: bool
    status: str
    planning_time_s: float
    validity_checks: int


def ompl_seed(seed: int) -> int:
    """The positive 31-bit seed OMPL gets for `seed` (OMPL ignores a seed of 0)."""
    return int(seed) % (2**31 - 1) + 1


def plan_path(
    low: ArrayLike,
    high: ArrayLike,
    start: ArrayLike,
    goal: ArrayLike,
    is_valid: Callable[[NDArray[np.float64]], bool],
    planner: Planner = "rrtconnect",
    time_budget_s: float = 1.0,
    seed: int = 0,
    resolution: float = 0.01,
    simplify: bool = True,
    max_checks: int | None = None,
) -> PlanResult:
    """Plan a collision-free path from `start` to `goal` (MotionPlanner, Algorithm 2).

    low, high: (D,) bounds of the configuration space (radians or metres), low < high.
    start, goal: (D,) configurations. is_valid(q (D,)) -> bool: whether q is allowed
    (collision-free); motions are checked by interpolation every `resolution` (Euclidean
    distance in configuration-space units), which is also the largest spacing of the
    returned path. planner: OMPL's RRTConnect or RRT*. time_budget_s: wall-time limit of
    the search. seed: seeds OMPL (see the module docstring for what is reproducible).
    simplify: shortcut the solution (OMPL's PathSimplifier) before interpolating it.
    max_checks: also stop after this many validity checks (makes "rrtstar" reproducible).
    A start or goal outside the bounds or invalid gives `solved=False`, not an exception.
    """
    lo, hi = np.asarray(low, np.float64), np.asarray(high, np.float64)
    q0, q1 = np.asarray(start, np.float64), np.asarray(goal, np.float64)
    dim = lo.shape[0]
    if lo.ndim != 1 or dim == 0 or any(a.shape != (dim,) for a in (hi, q0, q1)):
        raise ValueError(f"low, high, start and goal must all have shape (D,), got {lo.shape}")
    if not np.all(hi > lo):
        raise ValueError("every upper bound must exceed its lower bound")
    if planner not in PLANNERS:
        raise ValueError(f"planner must be one of {PLANNERS}, got {planner!r}")
    if resolution <= 0 or time_budget_s <= 0:
        raise ValueError("resolution and time_budget_s must be positive")
    t0 = time.perf_counter()
    empty = np.zeros((0, dim))
    for name, q in (("start", q0), ("goal", q1)):
        if np.any(q < lo) or np.any(q > hi) or not np.all(np.isfinite(q)):
            return PlanResult(empty, False, f"{name} outside bounds", 0.0, 0)
        if not is_valid(q.copy()):
            return PlanResult(empty, False, f"invalid {name}", time.perf_counter() - t0, 1)

    from ompl import util as ou

    previous_level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(ompl_seed(seed))  # see the module docstring
        return _solve(
            lo, hi, q0, q1, is_valid, planner, time_budget_s, resolution, simplify, max_checks, t0
        )
    finally:
        ou.setLogLevel(previous_level)


def _solve(
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    q0: NDArray[np.float64],
    q1: NDArray[np.float64],
    is_valid: Callable[[NDArray[np.float64]], bool],
    planner: str,
    time_budget_s: float,
    resolution: float,
    simplify: bool,
    max_checks: int | None,
    t0: float,
) -> PlanResult:
    from ompl import base as ob
    from ompl import geometric as og

    dim = lo.shape[0]
    space = ob.RealVectorStateSpace(dim)
    bounds = ob.RealVectorBounds(dim)
    for i in range(dim):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    checks = [0]

    def valid(state: Any) -> bool:
        checks[0] += 1
        return bool(is_valid(np.array([state[i] for i in range(dim)], dtype=np.float64)))

    setup.setStateValidityChecker(valid)
    start, goal = space.allocState(), space.allocState()
    for i in range(dim):
        start[i], goal[i] = float(q0[i]), float(q1[i])
    setup.setStartAndGoalStates(start, goal)
    info = setup.getSpaceInformation()
    info.setStateValidityCheckingResolution(min(1.0, resolution / space.getMaximumExtent()))
    search = og.RRTConnect(info) if planner == "rrtconnect" else og.RRTstar(info)
    setup.setPlanner(search)
    deadline = time.perf_counter() + time_budget_s
    limit = math.inf if max_checks is None else max_checks

    def stop() -> bool:
        return checks[0] >= limit or time.perf_counter() >= deadline

    status = setup.solve(ob.PlannerTerminationCondition(stop))
    solved = bool(setup.haveExactSolutionPath())
    text = str(status.asString())
    path: NDArray[np.float64] = np.zeros((0, dim))
    if solved:
        candidates = [_vertices(setup.getSolutionPath(), dim)]
        if simplify:
            setup.simplifySolution()
            candidates.insert(0, _vertices(setup.getSolutionPath(), dim))
        # OMPL checks motions at discrete points; the states between them are checked here
        # (an obstacle corner thinner than `resolution` can be clipped by a shortcut)
        for vertices in candidates:
            dense = densify(vertices, resolution)
            dense[0], dense[-1] = q0, q1
            if all(valid(d) for d in dense):
                path = dense
                break
        else:
            solved, text = False, "solution invalid between checked states"
    # release the OMPL objects (and the Python closures they hold) before returning
    del setup, search, info, start, goal, space, bounds, status
    return PlanResult(path, solved, text, time.perf_counter() - t0, checks[0])


def _vertices(path: Any, dim: int) -> NDArray[np.float64]:
    """(K, D) states of an OMPL PathGeometric."""
    count = path.getStateCount()
    return np.array([[path.getState(k)[i] for i in range(dim)] for k in range(count)])


def densify(vertices: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    """Piecewise-linear path through `vertices` (K, D) with every segment split into equal
    parts at most `step` long (Euclidean); the vertices are kept. Returns (M, D)."""
    pieces = [vertices[:1]]
    for a, b in itertools.pairwise(vertices):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
        s = np.arange(1, n + 1)[:, None] / n
        pieces.append(a + s * (b - a))
    return np.concatenate(pieces)
