"""`artic compose`: learnt CIPs chained by planning, with no further learning (thesis section
7.4, issue 21 part 8). The config, the skills read back and a trial are
`artic.planning.cip_compose`; the scene and the sequence `artic.planning.compose`.

One chunk per trial (resumable). Outputs: `trials.csv` (`TRIAL_COLUMNS`: one row per
trial, models used and skill: the grasp, the plan's validity checks, tracking error,
actions, success and how pi_c ended), `compose.csv` (models, trials, first_skill_success,
sequence_success; models `true`, and `perceived` with --perceive) and `summary.json`
(per models and skill: success, how pi_c ended, the median handle and yaw errors of
the robot's models; the skills' policy files, their sha256 as their train-cip
manifests list them, and `unchanged`: the file's sha256 computed again when the stage
ends equals it; composing learns nothing, and every trial checks the files before it
loads them).
"""

from __future__ import annotations

from pathlib import Path

from artic.artifacts.chunk_parts import take_csv_rows
from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.hashing import sha256_file
from artic.cli.stage_runner import Plan, Stage
from artic.planning.cip_compose import (
    COMPOSE_COLUMNS,
    TRIAL_COLUMNS,
    ComposeConfig,
    SkillFiles,
    compose_rows,
    per_skill,
    perception_models,
    run_trial,
)
from artic.planning.compose import check_compatible

#: each skill's train-cip folder (`<task>`) and the grasp-candidates folder of its grasps
INPUTS = {"door": "train-cip", "drawer": "train-cip", "slide": "train-cip", "lever": "train-cip",
          "door_grasps": "grasp-candidates", "drawer_grasps": "grasp-candidates",
          "slide_grasps": "grasp-candidates", "lever_grasps": "grasp-candidates"}  # fmt: skip


def _trial_file(trial: int) -> str:
    return f"trials/trial_{trial:03d}.csv"


def _plan(cfg: ComposeConfig, inputs: dict[str, Path]) -> Plan:
    # Bad input before a trial; without the inputs (a launcher counting the chunks of a
    # stage whose inputs are not made yet) the plan is the config's alone.
    if inputs:
        files = [SkillFiles(cfg, task, inputs) for task in cfg.skills]
        check_compatible([f.task for f in files])
        if cfg.perceive:
            perception_models(cfg, [f.task.object.category for f in files])
    return Plan([1] * cfg.trials, "trials")


def compose_chunk(cfg: ComposeConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Trial `chunk`: its rows into trials/trial_NNN.csv."""
    (tmp / "trials").mkdir()
    write_csv(tmp / _trial_file(chunk), TRIAL_COLUMNS, run_trial(cfg, inputs, chunk))
    return 1


def _finalize(
    cfg: ComposeConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    rows = take_csv_rows(work / _trial_file(t) for t in range(cfg.trials))
    (work / "trials").rmdir()
    write_csv(work / "trials.csv", TRIAL_COLUMNS, rows)
    table = compose_rows(rows)
    write_csv(work / "compose.csv", COMPOSE_COLUMNS, table)
    files = {task: SkillFiles(cfg, task, inputs) for task in cfg.skills}
    policies = {task: {"file": str(f.policy), "sha256": f.sha256,
                       "unchanged": sha256_file(f.policy) == f.sha256}
                for task, f in files.items()}  # fmt: skip
    write_json(work / "summary.json", {"skills": cfg.skills, "setting": cfg.setting,
               "trials": cfg.trials, "policies": policies,
               "compose": [dict(zip(COMPOSE_COLUMNS, r, strict=True)) for r in table],
               "per_skill": per_skill(rows)})  # fmt: skip
    return {f"{r[0]} models": f"first skill {r[2]:.2f}, sequence {r[3]:.2f} of {r[1]} trials"
            for r in table}  # fmt: skip


STAGE: Stage[ComposeConfig] = Stage(
    name="compose",
    help=(
        "Learnt CIPs chained by planning (section 7.4): head, grasp, pi_c, release, tail to "
        "the next skill; --perceive also on the objects the Chapter 3 network sees.\n\n"
        "Example: artic compose --skills door,drawer --perceive"
    ),
    conf="compose",
    schema=ComposeConfig,
    plan=_plan,
    chunk=compose_chunk,
    finalize=_finalize,
    options={"skills": "list", "perceive": "flag"},
    inputs=INPUTS,
    input_paths=lambda cfg: cfg.input_paths(),
)
