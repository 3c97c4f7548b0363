"""Where the arm goes in door episodes of a train-rmp run, against the door's evaluation
spheres (docs/reproduction.md, Chapter 6: why the door's row of Table 6.1 fails).

    python scripts/rmp_door_sweep.py artifacts/policy/rmp/door --episodes 3

For each controller's best seed (as `artic evaluate rmp` picks it): the final door angle
and the 5th-95th percentiles of the control points of links 1-6 over episodes without
spheres; then, of sphere centres placed by the environment itself (`RmpEnv._draw_spheres`:
in the task's obstacle volume, clear of the arm's start pose, of the door's swing and of
each other), the fraction that would touch each controller's swept arm.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from artic.learning.rmp_evaluate import RmpRun
from artic.learning.rmp_train import make_env

F64 = NDArray[np.float64]


def sweep(run: RmpRun, controller: str, episodes: int) -> tuple[F64, float]:
    """(points (N, 4): control point and radius every step; the last episode's door
    angle)."""
    env = make_env(run.cfg, controller, obstacles=False)  # type: ignore[arg-type]
    try:
        policy = run.policy(controller, run.best_seed(controller, 1), env)
        steps: list[F64] = []
        for j in range(episodes):
            obs, _ = env.reset(seed=1000 + j)
            done = False
            while not done:
                _, points = env.arm_state()
                assert points is not None
                steps.append(np.c_[points.positions, points.radii])
                action, _ = policy.predict(obs, deterministic=True)
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated
        return np.concatenate(steps), env.door_angle()
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a train-rmp output of the door task")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--draws", type=int, default=2000, help="sphere centres to place")
    args = parser.parse_args()
    run = RmpRun.open(args.folder, "door")
    swept: dict[str, F64] = {}
    for controller in ("vices", "rmp_vices"):
        points, angle = sweep(run, controller, args.episodes)
        swept[controller] = points
        lo, hi = np.percentile(points[:, :3], [5, 95], axis=0).round(2)
        print(f"{controller}: door angle {angle:.3f} rad; arm 5-95%: x {lo[0]}..{hi[0]}, "  # noqa: T201
              f"y {lo[1]}..{hi[1]}, z {lo[2]}..{hi[2]} m")  # fmt: skip
    env = make_env(run.cfg, "vices", obstacles=True)
    try:  # the environment's own placement (clear of the start pose and the swing)
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        clear = [c for _ in range(args.draws // 2) for c in env._draw_spheres(rng, [])]
    finally:
        env.close()
    print(f"{len(clear)} sphere centres placed")  # noqa: T201
    r = run.cfg.task.obstacles.radius
    for controller, points in swept.items():
        touch = np.mean(
            [np.any(np.linalg.norm(points[:, :3] - c, axis=1) < points[:, 3] + r) for c in clear]
        )
        print(f"{controller}: {100 * touch:.1f}% of placeable spheres touch the swept arm")  # noqa: T201


if __name__ == "__main__":
    main()
