"""`artic train-rmp`: PPO under VICES and RMP-VICES on one Chapter 6 task (section 6.4,
Fig. 6.2). The config and the training run are `artic.learning.rmp_train`; this stage
keeps the checkpoints and writes the outputs.

Each (controller, seed) is one chunk (shardable, resumable); inside a chunk the run is
checkpointed after every epoch in the work area (`state.pt`: tensors and plain data,
read with `weights_only=True`), so Ctrl-C and the same command again continue from the
last finished epoch to the bytes of an uninterrupted run.

Outputs: `learning_curve.csv` (controller, seed, epoch, steps (so far), episodes
(completed in the epoch), return_mean, return_std (of those), collisions,
joint_limit_events, force_median (N, of the epoch's collisions)), `forces.csv` (every
collision's contact force: Fig. 6.4), `timings.csv` (seconds per epoch, kept apart so
the curve is reproducible byte for byte), `policies/<controller>/seed_NNN/policy.pt`
and `summary.json`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from artic.artifacts.chunk_parts import take_csv_rows
from artic.artifacts.formats import write_csv, write_json
from artic.cli.stage_runner import Plan, Stage
from artic.learning.rmp_train import (
    CURVE,
    CURVE_COLUMNS,
    FORCE_COLUMNS,
    FORCES,
    TIMING,
    TrainRmpConfig,
)


def _run_dir(cfg: TrainRmpConfig, chunk: int) -> str:
    controller, index = cfg.run_of(chunk)
    return f"policies/{controller}/seed_{index:03d}"


def _plan(cfg: TrainRmpConfig, inputs: dict[str, Path]) -> Plan:
    return Plan([cfg.epochs] * (len(cfg.controllers) * cfg.seeds), "epochs")


def train_chunk(cfg: TrainRmpConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Run chunk `chunk` (controller, seed) with per-epoch checkpoints in the work area;
    writes its curve, forces and final policy into tmp."""
    from artic.artifacts.model_file import save_torch_file
    from artic.artifacts.resume import torch_checkpoint
    from artic.artifacts.workdir import WorkDir
    from artic.learning.rmp_train import policy_record, train_run

    resume = WorkDir(Path(cfg.out)).resume_dir(f"run_{chunk:03d}")
    state, save = torch_checkpoint(resume / "state.pt")
    rows, forces, policy = train_run(cfg, chunk, state, save)
    out = tmp / _run_dir(cfg, chunk)
    out.mkdir(parents=True)
    save_torch_file(out / "policy.pt", policy_record(cfg, chunk, policy))
    write_csv(out / "curve.csv", [*CURVE_COLUMNS, "seconds"], rows)
    write_csv(out / "forces.csv", FORCE_COLUMNS, forces)
    return len(rows)


def _finalize(
    cfg: TrainRmpConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    n = len(cfg.controllers) * cfg.seeds
    rows = take_csv_rows(work / _run_dir(cfg, c) / "curve.csv" for c in range(n))
    forces = take_csv_rows(work / _run_dir(cfg, c) / "forces.csv" for c in range(n))
    write_csv(work / CURVE, CURVE_COLUMNS, [r[:-1] for r in rows])
    write_csv(work / FORCES, FORCE_COLUMNS, forces)
    write_csv(work / TIMING, ["controller", "seed", "epoch", "seconds"],
              [[r[0], r[1], r[2], r[-1]] for r in rows])  # fmt: skip
    stats: dict[str, float | int | str] = {"task": cfg.task.name}
    final = [r for r in rows if int(r[2]) == cfg.epochs - 1]
    for controller in cfg.controllers:
        mine = [r for r in rows if r[0] == controller]
        last = [float(r[5]) for r in final if r[0] == controller]
        stats[f"{controller} final return"] = round(float(np.nanmean(last)), 3) if last else "nan"
        stats[f"{controller} collisions"] = sum(int(r[7]) for r in mine)
        stats[f"{controller} joint-limit events"] = sum(int(r[8]) for r in mine)
    summary = {"controllers": cfg.controllers, "seeds": cfg.seeds, "epochs": cfg.epochs, **stats}
    write_json(work / "summary.json", summary)
    return stats


STAGE: Stage[TrainRmpConfig] = Stage(
    name="train-rmp",
    help=(
        "PPO under VICES and RMP-VICES on one Chapter 6 task (section 6.4, Fig. 6.2).\n\n"
        "Example: artic train-rmp --task door"
    ),
    task_option=True,
    conf="train_rmp",
    schema=TrainRmpConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
)
