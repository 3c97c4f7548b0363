"""`artic evaluate cip` (thesis section 7.4, Fig. 7.3 and 7.4): its config and the
train-cip folders read back (`CipRun`). The statistics, targets and plots are
`artic.evaluation.cip_report`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pydantic import Field, field_validator

from artic.artifacts.formats import read_csv
from artic.artifacts.manifest import read_stage_config, verify_file
from artic.config.schemas import StageConfig
from artic.errors import InputError
from artic.learning.cip_train import CURVE, TrainCipConfig

TASKS = ("door", "drawer", "slide", "lever")


class EvaluateCipConfig(StageConfig):
    """The config of `artic evaluate cip` (conf/evaluate_cip/config.yaml)."""

    runs: dict[str, str | None] = Field(
        description="train-cip output folder of each task (door, drawer, slide, lever); "
        "null: the task is left out"
    )

    @field_validator("runs")
    @classmethod
    def _known(cls, value: dict[str, str | None]) -> dict[str, str | None]:
        unknown = sorted(set(value) - set(TASKS))
        if unknown:
            raise ValueError(f"runs: unknown task {unknown[0]} (door, drawer, slide, lever)")
        if all(v is None for v in value.values()):
            raise ValueError("runs: every task is null; give at least one train-cip folder")
        return value

    def input_paths(self) -> dict[str, Path]:
        """The folder of each task not set to null, in the order of `TASKS`."""
        return {t: Path(p) for t in TASKS if (p := self.runs.get(t)) is not None}


@dataclass(frozen=True)
class CipRun:
    """A finished train-cip folder: its scale (the experiment preset it was made with;
    none recorded: `cpu`, train-cip's default) and learning-curve rows (no header)."""

    folder: Path
    scale: str
    curve: list[list[str]]

    @classmethod
    def open(cls, folder: Path, task: str) -> CipRun:
        """The run in `folder`, checked to be a train-cip output of `task`."""
        cfg, manifest = read_stage_config(folder, "train-cip", TrainCipConfig)
        if cfg.task.name != task:
            raise InputError(f"runs.{task}: {folder} holds task '{cfg.task.name}'")
        curve = read_csv(verify_file(folder, manifest, CURVE))[1:]
        return cls(folder, manifest.choices.get("experiment") or "cpu", curve)
