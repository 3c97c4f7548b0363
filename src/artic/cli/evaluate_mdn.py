"""`artic evaluate mdn`: Table 3.1 for one category on its withheld objects.

Writes `report.md` (Table 3.1's rows: Mean, NN, ICP, Ours, Ours (densest), Ours +
refinement: kinematics/evaluate.py; the MDN's calibration), `summary.csv`, `errors.csv`
(per image and method), `refinement.csv`, `calibration.csv`, `calibration_refined.csv`
and `refined_intervals.csv` (the refined estimate's intervals: kinematics/intervals.py),
and plots: `errors.png`, `calibration.png`, `examples.png` (true axes green, predicted red).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pydantic import Field

from artic.artifacts.depth_dataset import DepthDataset, source_objects
from artic.artifacts.formats import write_csv
from artic.artifacts.model_store import choose_model
from artic.artifacts.workers import available_cpus
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig
from artic.errors import InputError
from artic.kinematics.config import CategoryRef, MdnEvaluateConfig

if TYPE_CHECKING:
    from artic.kinematics.data import DepthSplit
    from artic.kinematics.evaluate import Evaluation
    from artic.kinematics.predict import Predictor

METHODS = ("Mean", "NN", "ICP", "Ours", "Ours (densest)", "Ours + refinement")
MODEL = "model.pt"


class EvaluateMdnConfig(StageConfig):
    category: CategoryRef
    model: str | None = Field(None, description="train-mdn or shipped model folder; None: store's")
    depth: str = Field(description="a render-depth output folder (its test split is used)")
    objects: str | None = Field(
        None,
        description="the generate-dataset folder `depth` was rendered from (the ICP "
        "baseline's template); None: the one recorded in depth's manifest",
    )
    evaluate: MdnEvaluateConfig


def _plan(cfg: EvaluateMdnConfig, inputs: dict[str, Path]) -> Plan:
    DepthDataset.open_category(inputs["depth"], cfg.category.name)
    return Plan([1], "evaluations")


def evaluate_chunk(cfg: EvaluateMdnConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    import torch

    from artic.artifacts.object_dataset import ObjectDataset
    from artic.kinematics.baselines import IcpBaseline
    from artic.kinematics.data import DepthSplit, load_split
    from artic.kinematics.evaluate import evaluate
    from artic.kinematics.predict import Predictor

    threads = cfg.runtime.threads or available_cpus()
    torch.set_num_threads(threads)
    predictor = Predictor.load(inputs["model"] / MODEL, cfg.category.name)
    predictor = dataclasses.replace(predictor, threads=threads)  # the refinement's rays
    ds = DepthDataset.open(inputs["depth"])
    if ds.label_columns != list(predictor.codec.columns):
        raise InputError(f"depth: {inputs['depth']} has other label columns than the model")
    val = load_split(ds, "val")  # read once: the baselines' data and the calibration images
    train = DepthSplit.concat([load_split(ds, "train"), val])
    test = load_split(ds, "test").head(cfg.evaluate.max_test_images)
    if len(test) == 0 or len(train) == 0:
        raise InputError(f"depth: {inputs['depth']} has no test or no training images")
    objects = ObjectDataset.open(inputs["objects"])
    template = objects.template_spec(int(train.object_id[0]))
    icp = IcpBaseline(template, train.labels, predictor.camera)
    result = evaluate(
        predictor, train, test, icp, cfg.evaluate.icp_images, cfg.evaluate.batch_size,
        cfg.evaluate.levels, cfg.evaluate.refined_count(len(test)),
        val.head(cfg.evaluate.calibration_images),
    )  # fmt: skip
    _write(tmp, cfg, predictor, test, result)
    return 1


def _write(
    tmp: Path,
    cfg: EvaluateMdnConfig,
    predictor: Predictor,
    test: DepthSplit,
    result: Evaluation,
) -> None:
    from artic.evaluation import kinematics as table
    from artic.evaluation.plots import calibration_plot, error_histograms, examples_sheet

    unit = table.configuration_unit(predictor.joint_type)
    rows = table.summary_rows(result.errors, METHODS)
    write_csv(tmp / "summary.csv", table.SUMMARY_HEADER, rows)
    per_image = table.per_image_rows(result.errors, test.object_id)
    write_csv(tmp / "errors.csv", table.ERRORS_HEADER, per_image)
    columns = list(predictor.codec.columns)
    groups = table.calibration_groups(columns, predictor.dof)
    calibration = table.calibration_rows(result.coverage, groups)
    write_csv(tmp / "calibration.csv", ["nominal", *groups], calibration)
    error_histograms(tmp / "errors.png", result.errors, unit)
    calibration_plot(tmp / "calibration.png", result.coverage, groups)
    if cfg.evaluate.examples:
        k = min(cfg.evaluate.examples, len(test))
        pick = np.linspace(0, len(test) - 1, k).astype(int)
        examples_sheet(
            tmp / "examples.png", test.depth_m(pick), test.labels[pick],
            result.predictions["Ours"][pick], columns, predictor,
        )  # fmt: skip
    report = table.table_3_1_report(
        cfg.category.name, rows, result.coverage, groups, cfg.evaluate.levels, unit, len(test)
    )
    result.write_refinement(tmp, test.object_id, columns, predictor.dof)
    (tmp / "report.md").write_text(report + result.refinement_note(cfg.evaluate.levels))


def _finalize(
    cfg: EvaluateMdnConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    rows = [line.split(",") for line in (work / "summary.csv").read_text().splitlines()[1:]]
    stats: dict[str, float | int | str] = {"category": cfg.category.name}
    for row in rows:
        stats[f"{row[0]} pos/rot/config"] = " / ".join(f"{float(row[k]):.2f}" for k in (2, 4, 6))
    return stats


def _input_paths(cfg: EvaluateMdnConfig) -> dict[str, Path]:
    """model, depth and the object dataset depth was rendered from (`objects=`, or the
    one depth's manifest records), checked to be that dataset by its content hash."""
    depth = Path(cfg.depth)
    objects = source_objects(depth, None if cfg.objects is None else Path(cfg.objects))
    model = Path(cfg.model or choose_model("mdn", cfg.category.name, None, "model").path.parent)
    return {"model": model, "depth": depth, "objects": objects}


STAGE: Stage[EvaluateMdnConfig] = Stage(
    name="evaluate-mdn",
    command="evaluate mdn",
    help=(
        "Table 3.1 for one category: Ours vs Mean, NN, ICP, and calibration.\n\n"
        "Example: artic evaluate mdn category=microwave"
    ),
    conf="evaluate_mdn",
    schema=EvaluateMdnConfig,
    plan=_plan,
    chunk=evaluate_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"model": "train-mdn", "depth": "render-depth", "objects": "generate-dataset"},
    input_paths=_input_paths,
)
