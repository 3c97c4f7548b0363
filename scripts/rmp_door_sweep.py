"""Where the arm goes in door episodes of a train-rmp run, against the door's evaluation
spheres (docs/reproduction.md, Chapter 6: why the door's row of Table 6.1 fails).

    python scripts/rmp_door_sweep.py artifacts/policy/rmp/door --episodes 3

For each controller's best seed (as `artic evaluate rmp` picks it): the final door angle
and the 5th-95th percentiles of the control points of links 1-6 over episodes without
spheres; then, of sphere centres drawn in the task's obstacle volume that pass the
environment's placement rules (clear of the arm's start pose and of the door's swing),
the fraction that would touch each controller's swept arm.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from artic.learning.rmp_evaluate import RmpRun
from artic.learning.rmp_train import make_env

F64 = NDArray[np.float64]


def sweep(run: RmpRun, controller: str, episodes: int) -> tuple[F64, F64, float]:
    """(points (N, 4): control point and radius every step; the start pose's points;
    the last episode's door angle)."""
    env = make_env(run.cfg, controller, obstacles=False)  # type: ignore[arg-type]
    try:
        policy = run.policy(controller, run.best_seed(controller, 1), env)
        steps: list[F64] = []
        start: F64 | None = None
        for j in range(episodes):
            obs, _ = env.reset(seed=1000 + j)
            done = False
            while not done:
                _, points = env.arm_state()
                assert points is not None
                row = np.c_[points.positions, points.radii]
                start = row if start is None else start
                steps.append(row)
                action, _ = policy.predict(obs, deterministic=True)
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated
        assert start is not None
        return np.concatenate(steps), start, env.door_angle()
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a train-rmp output of the door task")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--draws", type=int, default=4000)
    args = parser.parse_args()
    run = RmpRun.open(args.folder, "door")
    task = run.cfg.task
    scene = task.scene
    swept: dict[str, F64] = {}
    start: F64 | None = None
    for controller in ("vices", "rmp_vices"):
        points, start, angle = sweep(run, controller, args.episodes)
        swept[controller] = points
        lo, hi = np.percentile(points[:, :3], [5, 95], axis=0).round(2)
        print(f"{controller}: door angle {angle:.3f} rad; arm 5-95%: x {lo[0]}..{hi[0]}, "  # noqa: T201
              f"y {lo[1]}..{hi[1]}, z {lo[2]}..{hi[2]} m")  # fmt: skip
    assert start is not None
    obstacles = task.obstacles
    r, keep = obstacles.radius, obstacles.radius + obstacles.clearance
    hinge = np.array([scene.x - scene.depth / 2, scene.y - scene.chirality * scene.width / 2])  # type: ignore[union-attr]
    rng = np.random.default_rng(0)
    box = obstacles.volume
    centres = np.asarray(box.centre) + np.asarray(box.half_extents) * rng.uniform(
        -1, 1, (args.draws, 3)
    )
    clear = [
        c
        for c in centres
        if c[2] >= r
        and not np.any(np.linalg.norm(start[:, :3] - c, axis=1) < keep + start[:, 3])
        and np.linalg.norm(c[:2] - hinge) >= scene.width + keep  # type: ignore[union-attr]
    ]
    print(f"placeable: {len(clear)} of {args.draws} draws")  # noqa: T201
    for controller, points in swept.items():
        touch = np.mean(
            [np.any(np.linalg.norm(points[:, :3] - c, axis=1) < points[:, 3] + r) for c in clear]
        )
        print(f"{controller}: {100 * touch:.1f}% of placeable spheres touch the swept arm")  # noqa: T201


if __name__ == "__main__":
    main()
