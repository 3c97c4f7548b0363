"""Chapter 6: control steps per second of the Chapter 6 environments under VICES and
RMP-VICES (one process = one core; 20 Hz actions, 12 physics substeps each with the
controller, random actions, resets included). Targets (issue 20): >= 250 steps/s per
core under VICES, >= 100 under RMP-VICES. Interleaved repeats, medians.

Usage: python bench/rmp_speed.py [--steps 200] [--repeats 3] [--tasks traj door push]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

from artic.reproducibility import pin_numerics

pin_numerics()


def measure(
    tasks: list[str], steps: int, repeats: int, clock: Callable[[], float]
) -> dict[str, dict[str, float]]:
    """{task: {controller: median steps/s}} over `repeats` interleaved runs, per second
    of `clock`."""
    from artic.sim.rmp_envs import CONTROLLERS, measure_steps_per_second

    samples: dict[str, dict[str, list[float]]] = {t: {c: [] for c in CONTROLLERS} for t in tasks}
    for r in range(repeats):
        for task in tasks:
            for controller in CONTROLLERS:
                rate = measure_steps_per_second(task, controller, n=steps, seed=r, clock=clock)
                samples[task][controller].append(rate)
    return {t: {c: statistics.median(v) for c, v in cs.items()} for t, cs in samples.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--tasks", nargs="+", default=["traj", "door", "push"])
    parser.add_argument(
        "--cpu-time",
        action="store_true",
        help="rates per second of this process' CPU time (a per-core rate on a busy machine)",
    )
    args = parser.parse_args()
    clock = time.process_time if args.cpu_time else time.perf_counter
    rates = measure(args.tasks, args.steps, args.repeats, clock)
    load = os.getloadavg()[0]
    unit = "CPU" if args.cpu_time else "wall"
    print(f"steps per second of {unit} time; load average {load:.1f}")
    print("| task | VICES steps/s | RMP-VICES steps/s |")
    print("|---|---|---|")
    for task, by in rates.items():
        print(f"| {task} | {by['vices']:.0f} | {by['rmp_vices']:.0f} |")


if __name__ == "__main__":
    main()
