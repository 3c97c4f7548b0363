"""`artic cip-demos`: ten expert demonstrations of a CIP's contact phase (thesis section
7.3, issue 21 part 5) from CIP starts of a grasp-candidates folder (`initiation_set=`),
for CIP+BC, and ten from home reaching for such a start (the reach planned), for E2E+BC.
The config, the starts (the best-scored grasp; why: the module's docstring) and the
recording are `artic.planning.cip_demos`; the expert is `artic.planning.cip_expert`.

One chunk. Outputs: `demos.npz` (every transition with its episode index, and success,
from_home, seed and grasp per episode: `learning.cip_train.DEMO_ARRAYS`) and `summary.json` (one
record per episode). Every episode is written; train-cip learns from the successful
ones only (`learning.cip_train.read_demonstrations`).
"""

from __future__ import annotations

from pathlib import Path

from artic.artifacts.formats import read_json, write_json, write_npz
from artic.cli.stage_runner import Plan, Stage
from artic.learning.cip_train import DEMOS_NPZ
from artic.planning.cip_demos import CipDemosConfig, read_initiation_set, record_demos


def _plan(cfg: CipDemosConfig, inputs: dict[str, Path]) -> Plan:
    read_initiation_set(inputs["initiation_set"], cfg.task)  # bad input before any episode
    return Plan([cfg.demos + cfg.home_demos], "demos")


def demos_chunk(cfg: CipDemosConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Record the demonstrations; writes demos.npz and summary.json into tmp."""
    recording = record_demos(cfg, read_initiation_set(inputs["initiation_set"], cfg.task))
    write_npz(tmp / DEMOS_NPZ, recording.arrays)
    episodes = recording.episodes
    write_json(tmp / "summary.json", {"task": cfg.task.name, "demos": cfg.demos,
               "home_demos": cfg.home_demos,
               "succeeded": sum(e["success"] for e in episodes if not e["from_home"]),
               "succeeded_from_home": sum(e["success"] for e in episodes if e["from_home"]),
               "episodes": episodes})  # fmt: skip
    return cfg.demos + cfg.home_demos


def _finalize(
    cfg: CipDemosConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    summary = read_json(work / "summary.json")
    steps = sum(e["steps"] for e in summary["episodes"] if e["success"])
    return {"task": cfg.task.name,
            "succeeded": f"{summary['succeeded']} of {cfg.demos} from CIP starts, "
                         f"{summary['succeeded_from_home']} of {cfg.home_demos} from home",
            "transitions used by train-cip": steps}  # fmt: skip


STAGE: Stage[CipDemosConfig] = Stage(
    name="cip-demos",
    help=(
        "Expert demonstrations of a CIP's contact phase from CIP starts (for CIP+BC).\n\n"
        "Example: artic cip-demos --task door"
    ),
    task_option=True,
    conf="cip_demos",
    schema=CipDemosConfig,
    plan=_plan,
    chunk=demos_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"initiation_set": "grasp-candidates"},
    input_paths=lambda cfg: {"initiation_set": Path(cfg.initiation_set)},
)
