"""`artic train-cip`: TD3 on one Chapter 7 task under the settings of the ablation (thesis
section 7.3, Algorithm 3; Fig. 7.3, 7.4). The config and a run are
`artic.learning.cip_train`; the grasp settings' head is `artic.planning.cip_head`.

Each (setting, seed) is one chunk (shardable, resumable); inside a chunk the run is
checkpointed after every block of `train.eval_every` episodes in the work area
(`state.pt`: tensors and plain data, read with `weights_only=True`), so Ctrl-C and the
same command again continue from the last finished block to the bytes of an
uninterrupted run. Inputs: `initiation_set=` (a grasp-candidates folder) for the
settings that start at a grasp, `demos=` (a cip-demos folder; its successful episodes)
for cip_bc and e2e_bc.

Outputs: `learning_curve.csv` (`CURVE_COLUMNS`: setting, seed, episode, success,
success_best, violation_rate, violation_rate_train, return_mean),
`policies/<setting>/seed_NNN/policy.pt` (the actor's weights: `policy_record`) and
`summary.json`.
"""

from __future__ import annotations

from pathlib import Path

from artic.artifacts.chunk_parts import take_csv_rows
from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.model_file import save_torch_file
from artic.artifacts.resume import torch_checkpoint
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.learning.cip_train import (
    CURVE,
    CURVE_COLUMNS,
    SETTINGS,
    HomeStarts,
    Starts,
    TrainCipConfig,
    policy_record,
    read_demonstrations,
    run_seed,
    run_summary,
    start_margin,
    train_run,
)
from artic.planning.cip_demos import read_initiation_set
from artic.planning.cip_head import GraspStarts


def _run_dir(cfg: TrainCipConfig, chunk: int) -> str:
    setting, index = cfg.run_of(chunk)
    return f"policies/{setting}/seed_{index:03d}"


def _plan(cfg: TrainCipConfig, inputs: dict[str, Path]) -> Plan:
    # Bad input before any run; without the inputs (a launcher counting the chunks of a
    # stage whose inputs are not made yet) the plan is the config's alone.
    if "initiation_set" in inputs:
        read_initiation_set(inputs["initiation_set"], cfg.task)
    if "demos" in inputs:
        for setting in cfg.settings:
            if SETTINGS[setting].demos:
                read_demonstrations(inputs["demos"], cfg.task, SETTINGS[setting].grasp == "home")
    return Plan([cfg.train.episodes] * (len(cfg.settings) * cfg.seeds), "episodes")


def train_chunk(cfg: TrainCipConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Run chunk `chunk` (setting, seed) with per-block checkpoints in the work area;
    writes its curve and final policy (the last checkpoint's actor) into tmp."""
    setting, index = cfg.run_of(chunk)
    spec = SETTINGS[setting]
    margin = start_margin(cfg.task, setting)
    starts: Starts = HomeStarts()
    if spec.grasp != "home":
        initiation_set = read_initiation_set(inputs["initiation_set"], cfg.task)
        starts = GraspStarts(initiation_set, setting, margin, cfg.head)
    demos = (
        read_demonstrations(inputs["demos"], cfg.task, spec.grasp == "home") if spec.demos else None
    )
    state_file = WorkDir(Path(cfg.out)).resume_dir(f"run_{chunk:03d}") / "state.pt"
    state, save = torch_checkpoint(state_file)
    seed = run_seed(cfg.seed, index)
    rows = train_run(cfg.task, setting, seed, cfg.train, starts, demos, state, save)
    final, _ = torch_checkpoint(state_file)  # saved after every block, the last one included
    assert final is not None
    out = tmp / _run_dir(cfg, chunk)
    out.mkdir(parents=True)
    save_torch_file(out / "policy.pt", policy_record(cfg, chunk, final))
    write_csv(out / "curve.csv", CURVE_COLUMNS, [r._replace(seed=index) for r in rows])
    return cfg.train.episodes


def _finalize(
    cfg: TrainCipConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    n = len(cfg.settings) * cfg.seeds
    rows = take_csv_rows(work / _run_dir(cfg, c) / "curve.csv" for c in range(n))
    write_csv(work / CURVE, CURVE_COLUMNS, rows)
    summary, stats = run_summary(cfg, rows)
    write_json(work / "summary.json", summary)
    return stats


STAGE: Stage[TrainCipConfig] = Stage(
    name="train-cip",
    help=(
        "TD3 on one Chapter 7 task under the seven settings of the ablation (section 7.3, "
        "Algorithm 3).\n\nExample: artic train-cip --task door"
    ),
    task_option=True,
    conf="train_cip",
    schema=TrainCipConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    inputs={"initiation_set": "grasp-candidates", "demos": "cip-demos"},
    input_paths=lambda cfg: cfg.input_paths(),
)
