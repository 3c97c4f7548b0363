"""Chapter 7's safety envelope sigma (issue 21's target): the share of random-action
episodes in which a joint comes within B's threshold (0.1 rad) of a limit, with sigma
and without it, on each task.

Each episode starts as the Safety setting's do (a grasp of the task's initiation set
drawn at random, naive IK with every joint outside sigma1, the gripper closed on it;
`planning.cip_head.GraspStarts`; the same starts with and without sigma)
at an episode pose drawn from its seed, then takes uniform random actions in [-1, 1]^13
for the task's horizon (250 actions), lost contact not ending it (only the joint limit
does: that is what is counted). The initiation sets are built in-process as
`artic grasp-candidates` builds them (100 grasps, seed 0). Target: at most 2% with
sigma; without it: measured.

Usage: python bench/cip_envelope.py [--episodes 50] [--tasks door drawer slide lever]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

from artic.reproducibility import pin_numerics

pin_numerics()

import numpy as np  # noqa: E402


def random_actions(seed: int) -> Callable[[np.ndarray], np.ndarray]:
    """A policy of uniform random actions in [-1, 1]^13 drawn from `seed`."""
    rng = np.random.default_rng(seed)
    return lambda obs: rng.uniform(-1.0, 1.0, 13).astype(np.float32)


def violation_rates(task_name: str, episodes: int) -> dict[str, float]:
    """{"sigma": share, "none": share} of `episodes` random-action episodes of the task
    ending at B's joint limit, with and without the envelope (the same starts)."""
    from artic.learning.cip_train import episode_seed, evaluate_policy, start_margin
    from artic.planning.cip_grasps import build_initiation_set
    from artic.planning.cip_head import GraspStarts
    from artic.sim.cip_envs import CipEnv
    from artic.sim.cip_tasks import get_cip_task

    task = get_cip_task(task_name)
    initiation_set = build_initiation_set(task, np.random.default_rng(0))
    seeds = [episode_seed(0, -k - 1) for k in range(episodes)]
    out = {}
    for name, safety in (("sigma", True), ("none", False)):
        starts = GraspStarts(initiation_set, "safety", start_margin(task, "safety"))
        env = CipEnv(task, safety=safety, contact_termination=False)
        try:
            records = evaluate_policy(random_actions(1), env, starts, seeds)
        finally:
            env.close()
        out[name] = float(np.mean([r.violation for r in records]))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--tasks", nargs="+", default=["door", "drawer", "slide", "lever"])
    args = parser.parse_args()
    print("| task | episodes | within 0.1 rad of a limit, sigma | without sigma | wall s |")
    print("|---|---|---|---|---|")
    for task in args.tasks:
        start = time.perf_counter()
        rates = violation_rates(task, args.episodes)
        wall = time.perf_counter() - start
        print(f"| {task} | {args.episodes} | {100 * rates['sigma']:.0f}% | "
              f"{100 * rates['none']:.0f}% | {wall:.0f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
