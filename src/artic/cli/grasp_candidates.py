"""`artic grasp-candidates`: the grasp candidates G on the handle's scanned cloud, their
IK solutions, filters and scores, and the initiation set I_c over them (thesis section
7.2.1, Algorithm 3 lines 1-3). The config is `artic.planning.cip_demos`; the work is
`artic.planning.cip_grasps.build_initiation_set`, drawing from `default_rng(seed)`.

One chunk. Output: `initiation_set.json` (docs/cip.md); the filter counts are the
manifest's stats. No grasp left is bad input (exit 2, with every filter's count).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from artic.cli.stage_runner import Plan, Stage
from artic.planning.cip_demos import (
    INITIATION_SET,
    GraspCandidatesStageConfig,
    initiation_set_stats,
)
from artic.planning.cip_grasps import InitiationSet, build_initiation_set


def _plan(cfg: GraspCandidatesStageConfig, inputs: dict[str, Path]) -> Plan:
    return Plan([cfg.grasps], "grasps")


def candidates_chunk(
    cfg: GraspCandidatesStageConfig, inputs: dict[str, Path], chunk: int, tmp: Path
) -> int:
    """Sample, filter and score the grasps; writes initiation_set.json into tmp."""
    rng = np.random.default_rng(cfg.seed)
    initiation_set = build_initiation_set(cfg.task, rng, cfg.grasps, cfg.candidates)
    (tmp / INITIATION_SET).write_text(initiation_set.to_json(), encoding="utf-8")
    return cfg.grasps


def _finalize(
    cfg: GraspCandidatesStageConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    text = (work / INITIATION_SET).read_text(encoding="utf-8")
    return initiation_set_stats(InitiationSet.from_json(text))


STAGE: Stage[GraspCandidatesStageConfig] = Stage(
    name="grasp-candidates",
    help=(
        "Grasp candidates on the handle's cloud, IK, filters, scores: the initiation set "
        "I_c (Algorithm 3, lines 1-3).\n\nExample: artic grasp-candidates --task door"
    ),
    task_option=True,
    conf="grasp_candidates",
    schema=GraspCandidatesStageConfig,
    plan=_plan,
    chunk=candidates_chunk,
    finalize=_finalize,
    one_chunk=True,
)
