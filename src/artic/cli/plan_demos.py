"""`artic plan-demos`: motion-planned demonstrations of a Chapter 5 task (Algorithm 2).

The config and the per-demo work are `artic.planning.task_demos`. The task's world
(`artic.sim.world.TaskWorld`, built once per process) lends the robot's
inverse kinematics, collision check and forward kinematics as functions to
`artic.planning.demos.plan_demo`, which plans on a kinematic model of the object: the
world's true one, a noisy copy, or the one the Chapter 3 MDN (`model.mdn`, a stage
input) predicts from a rendered depth view (`model.source`). Demo i is drawn from a generator
seeded by (seed, i); chunks hold `demos.per_chunk` demos, so any sharding writes the same
demo files. Each planned demo is then executed in the simulator by joint-velocity
tracking (`artic.planning.task_demos.execute`), and the object configuration it achieves
is recorded: the plan is kinematic, so it may not move a heavy drawer all the way
(thesis Fig. 5.3b).

Outputs are the same bytes for the same seed and config, whatever the sharding, except
`timings.json`: the wall-clock planning time of each demo lives there, not in demos.json.
"""

from __future__ import annotations

import functools
import math
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

from artic.artifacts.chunk_parts import take_json
from artic.artifacts.demo_dataset import DEMOS_JSON, demo_name, write_demo
from artic.artifacts.formats import write_json
from artic.cli.stage_runner import Plan, Stage
from artic.errors import InputError
from artic.planning.models import ModelConfig
from artic.planning.task_demos import (
    PlanDemosConfig,
    demo_stats,
    demos_index,
    mdn_choice,
    mdn_input,
    plan_one,
    planning_model,
    timings_record,
)
from artic.sim.tasks import TaskConfig

if TYPE_CHECKING:
    from artic.objects.model import ArticulatedObject
    from artic.sim.world import TaskWorld

TIMINGS_JSON = "timings.json"  # wall-clock planning times: the one output that varies by run
RECORDS = "records"  # per-demo JSON records, merged into demos.json by finalize


@functools.lru_cache(maxsize=1)
def _world(task_json: str) -> TaskWorld:
    """One world per process (chunks reuse it; `reset` restores its initial state)."""
    from artic.sim.world import TaskWorld

    # rng None: the task's nominal object geometry (no geometry_jitter draw)
    return TaskWorld.create(TaskConfig.model_validate_json(task_json), None)


def _indices(cfg: PlanDemosConfig, chunk: int) -> range:
    size = cfg.demos.per_chunk
    return range(chunk * size, min((chunk + 1) * size, cfg.demos.count))


def _plan(cfg: PlanDemosConfig, inputs: dict[str, Path]) -> Plan:
    if cfg.model.source == "predicted":
        _cached_model(cfg)  # bad input (model, camera) fails here, before any chunk
    size, n = cfg.demos.per_chunk, cfg.demos.count
    return Plan([min(size, n - c * size) for c in range(math.ceil(n / size))], "demos")


@functools.lru_cache(maxsize=1)
def _model(
    task_json: str, model_json: str, seed: int, mdn: str | None
) -> tuple[ArticulatedObject, dict[str, Any]]:
    """The planning model of a config, drawn (or predicted) once per process."""
    cfg = ModelConfig.model_validate_json(model_json)
    return planning_model(cfg, seed, _world(task_json), Path(mdn) if mdn else None)


def _cached_model(cfg: PlanDemosConfig) -> tuple[ArticulatedObject, dict[str, Any]]:
    mdn = str(mdn_choice(cfg).path) if cfg.model.source == "predicted" else None
    return _model(cfg.task.model_dump_json(), cfg.model.model_dump_json(), cfg.seed, mdn)


def plan_chunk(cfg: PlanDemosConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Plan the demos of chunk `chunk`: `demo_###.npz` for each that succeeded and a
    record for each into tmp."""
    world = _world(cfg.task.model_dump_json())
    (tmp / RECORDS).mkdir()
    done = 0
    for index in _indices(cfg, chunk):
        demo, record = plan_one(cfg, world, _cached_model(cfg)[0], index)
        if demo is not None:
            write_demo(tmp / demo_name(index), demo)
        write_json(tmp / RECORDS / f"demo_{index:03d}.json", record)
        done += 1
    return done


def _finalize(
    cfg: PlanDemosConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    records = take_json(work / RECORDS / f"demo_{i:03d}.json" for i in range(cfg.demos.count))
    # wall-clock times vary from run to run: they go to timings.json, demos.json stays
    # deterministic
    times = [r.pop("planning_time_s") for r in records]
    ok = [r for r in records if r["status"] == "ok"]
    # a perceived model may be too wrong to plan on: that is a result, not bad input
    if not ok and cfg.model.source != "predicted":
        reasons = sorted({r["reason"] for r in records})
        raise InputError(
            f"task {cfg.task.name}: no demo could be planned to the goal q_O* = "
            f"{cfg.task.goal} ({'; '.join(reasons)})"
        )
    from artic.sim.world import TaskWorld

    # the true model's record needs no world; a noisy one is drawn from it (cached)
    model_record: dict[str, Any] = (
        {"source": "true"} if cfg.model.source == "true" else _cached_model(cfg)[1]
    )
    write_json(work / DEMOS_JSON, demos_index(cfg, records, model_record, TaskWorld.n_robot))
    write_json(work / TIMINGS_JSON, timings_record(cfg, records, times))
    shutil.rmtree(work / RECORDS)
    return demo_stats(cfg, records, times, model_record)


STAGE: Stage[PlanDemosConfig] = Stage(
    name="plan-demos",
    help=(
        "Motion-planned demonstrations on a kinematic model (Algorithm 2).\n\n"
        "Example: artic plan-demos --task drawer"
    ),
    task_option=True,
    conf="plan_demos",
    schema=PlanDemosConfig,
    plan=_plan,
    chunk=plan_chunk,
    finalize=_finalize,
    inputs={"mdn": "train-mdn"},
    input_paths=mdn_input,
)
