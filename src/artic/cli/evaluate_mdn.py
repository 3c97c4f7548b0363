"""`artic evaluate mdn`: Table 3.1 for one category on its withheld objects.

Writes `report.md` (the Table 3.1 row block: Mean, NN, ICP, Ours with mean and standard
deviation of each error, and Ours with the `densest` estimator; the calibration of the
MDN's intervals), `summary.csv`, `errors.csv` (per image and method), `calibration.csv`,
and plots: `errors.png` (histograms), `calibration.png` (empirical against nominal
coverage), `examples.png` (true axes green, predicted red).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
from pydantic import Field

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.formats import write_csv
from artic.artifacts.manifest import MANIFEST, read_manifest
from artic.cli.stage_runner import Plan, Stage, available_cpus
from artic.cli.train_mdn import KIND, MODEL, CategoryRef
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError

if TYPE_CHECKING:
    from artic.kinematics.data import DepthSplit
    from artic.kinematics.evaluate import Evaluation
    from artic.kinematics.predict import Predictor

METHODS = ("Mean", "NN", "ICP", "Ours", "Ours (densest)")


class EvaluateOptions(Strict):
    max_test_images: int | None = Field(None, gt=0)
    icp_images: int = Field(500, ge=0)
    batch_size: int = Field(64, gt=0)
    levels: tuple[Annotated[float, Field(gt=0, lt=1)], ...] = Field(
        (0.5, 0.9, 0.95), min_length=1, description="nominal coverages, each in (0, 1)"
    )
    examples: int = Field(8, ge=0)


class EvaluateMdnConfig(StageConfig):
    category: CategoryRef
    model: str = Field(description="a train-mdn output folder")
    depth: str = Field(description="a render-depth output folder (its test split is used)")
    objects: str | None = Field(
        None,
        description="the generate-dataset folder `depth` was rendered from (the ICP "
        "baseline's template); None: the one recorded in depth's manifest",
    )
    evaluate: EvaluateOptions


def _plan(cfg: EvaluateMdnConfig, inputs: dict[str, Path]) -> Plan:
    DepthDataset.open_category(inputs["depth"], cfg.category.name)
    return Plan([1], "evaluations")


def evaluate_chunk(cfg: EvaluateMdnConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    import torch

    from artic.artifacts.model_file import load_model_file
    from artic.artifacts.object_dataset import ObjectDataset
    from artic.kinematics.baselines import IcpBaseline
    from artic.kinematics.data import DepthSplit, load_split
    from artic.kinematics.evaluate import evaluate
    from artic.kinematics.predict import Predictor

    torch.set_num_threads(cfg.runtime.threads or available_cpus())
    payload = load_model_file(inputs["model"] / MODEL, KIND, cfg.category.name)
    predictor = Predictor.from_payload(payload)
    ds = DepthDataset.open(inputs["depth"])
    if ds.label_columns != list(predictor.codec.columns):
        raise InputError(f"depth: {inputs['depth']} has other label columns than the model")
    train_parts = [load_split(ds, s) for s in ("train", "val")]
    train = DepthSplit(
        np.concatenate([p.depth for p in train_parts]),
        np.concatenate([p.labels for p in train_parts]),
        np.concatenate([p.object_id for p in train_parts]),
    )
    test = load_split(ds, "test")
    n = cfg.evaluate.max_test_images
    if n is not None:
        test = DepthSplit(test.depth[:n], test.labels[:n], test.object_id[:n])
    if len(test) == 0 or len(train) == 0:
        raise InputError(f"depth: {inputs['depth']} has no test or no training images")
    objects = ObjectDataset.open(inputs["objects"])
    template = objects.template_spec(int(train.object_id[0]))
    icp = IcpBaseline(template, train.labels, predictor.camera)
    result = evaluate(
        predictor, train, test, icp, cfg.evaluate.icp_images, cfg.evaluate.batch_size,
        cfg.evaluate.levels,
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
    from artic.evaluation.kinematics import METRICS, configuration_unit
    from artic.evaluation.plots import calibration_plot, error_histograms, examples_sheet

    unit = configuration_unit(predictor.joint_type)
    rows: list[list[float | int | str]] = []
    for name in METHODS:
        if name in result.errors:
            e = result.errors[name]
            stats = [v for m in METRICS for v in (float(e[m].mean()), float(e[m].std()))]
            rows.append([name, len(e["position_cm"]), *stats])
    header = ["method", "images"] + [f"{m}_{s}" for m in METRICS for s in ("mean", "std")]
    write_csv(tmp / "summary.csv", header, rows)
    per_image = []
    for name, e in result.errors.items():
        for i in range(len(e["position_cm"])):
            per_image.append([name, i, int(test.object_id[i])] + [float(e[m][i]) for m in METRICS])
    write_csv(tmp / "errors.csv", ["method", "image", "object_id", *METRICS], per_image)
    columns = list(predictor.codec.columns)
    groups = _calibration_groups(columns, predictor.dof)
    levels = sorted(result.coverage)
    write_csv(
        tmp / "calibration.csv",
        ["nominal", *groups],
        [[lv] + [float(np.nanmean(result.coverage[lv][idx])) for idx in groups.values()]
         for lv in levels],
    )  # fmt: skip
    error_histograms(tmp / "errors.png", result.errors, unit)
    calibration_plot(tmp / "calibration.png", result.coverage, groups)
    if cfg.evaluate.examples:
        k = min(cfg.evaluate.examples, len(test))
        pick = np.linspace(0, len(test) - 1, k).astype(int)
        examples_sheet(
            tmp / "examples.png", test.depth_m(pick), test.labels[pick],
            result.predictions["Ours"][pick], columns, predictor,
        )  # fmt: skip
    _report(tmp, cfg, rows, result, groups, unit, len(test))


def _calibration_groups(columns: list[str], dof: int) -> dict[str, list[int]]:
    col = {c: i for i, c in enumerate(columns)}
    origins = [col[f"j{j}_origin_{a}"] for j in range(dof) for a in "xyz"]
    return {
        "all predicted columns": list(range(len(columns))),
        "axis origin": origins,
        "axis yaw": [col["pose_yaw"]],
        "configuration": [col[f"j{j}_q"] for j in range(dof)],
    }


def _report(
    tmp: Path,
    cfg: EvaluateMdnConfig,
    rows: list[list[float | int | str]],
    result: Evaluation,
    groups: dict[str, list[int]],
    unit: str,
    n_test: int,
) -> None:
    from artic.evaluation.kinematics import METRICS

    name, n = cfg.category.name, len(METRICS)  # the header names the METRICS in order
    lines = [
        f"# Table 3.1: {name}",
        "",
        f"{n_test} test images of withheld objects; errors as mean ± std. "
        "Ours: the mean of the MDN's most likely component, the one of largest weight "
        "(section 3.3.1); Ours (densest): the component mean of highest mixture density. "
        "Rot. (thesis' metric): the rotation error as the thesis' evaluation code computes "
        "it, for comparison with its Table 3.1 (docs/reproduction.md).",
        "",
        f"| {name} | Axis Pos. Error (cm) | Axis Rot. Error (deg) "
        f"| Config. Error ({unit}) | Rot. (thesis' metric, deg) | images |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [f"{float(r[2 + 2 * k]):.2f} ± {float(r[3 + 2 * k]):.2f}" for k in range(n)]
        lines.append(f"| {r[0]} | {' | '.join(cells)} | {r[1]} |")
    lines += [
        "",
        "## Calibration of the MDN",
        "",
        "Fraction of true values inside the predicted central intervals of each label's "
        "marginal (mean over the columns of each group).",
        "",
        "| nominal | " + " | ".join(groups) + " |",
        "|---|" + "---|" * len(groups),
    ]
    for lv in cfg.evaluate.levels:
        cells = [f"{100 * np.nanmean(result.coverage[lv][idx]):.1f}%" for idx in groups.values()]
        lines.append(f"| {100 * lv:.0f}% | " + " | ".join(cells) + " |")
    lines += ["", "Plots: errors.png, calibration.png, examples.png. Data: summary.csv, "
              "errors.csv, calibration.csv.", ""]  # fmt: skip
    (tmp / "report.md").write_text("\n".join(lines))


def _finalize(
    cfg: EvaluateMdnConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    lines = (work / "summary.csv").read_text().splitlines()
    stats: dict[str, float | int | str] = {"category": cfg.category.name}
    for line in lines[1:]:
        cells = line.split(",")
        stats[f"{cells[0]} pos/rot/config"] = " / ".join(
            f"{float(cells[k]):.2f}" for k in (2, 4, 6)
        )
    return stats


def recorded_objects(depth: Path) -> tuple[list[Path], str]:
    """Where the object dataset `depth` was rendered from may lie, most likely first,
    and its content hash, from depth's manifest. A relative recorded path is relative
    to the directory render-depth ran in: found from the depth folder's own recorded
    `out` (when the folder has not moved since), else tried beside the current
    directory."""
    manifest = read_manifest(depth, expected_stage="render-depth")
    record = manifest.inputs.get("dataset")
    if record is None:
        raise InputError(f"depth: {depth / MANIFEST} records no dataset input; pass objects=PATH")
    recorded = Path(record.path)
    if recorded.is_absolute():
        return [recorded], record.content_hash
    candidates: list[Path] = []
    out = Path(str(manifest.config.get("out", "")))
    here = depth.resolve()
    if str(out) not in ("", ".") and not out.is_absolute():
        n = len(out.parts)
        if len(here.parts) > n and here.parts[-n:] == out.parts:
            candidates.append(here.parents[n - 1] / recorded)
    candidates.append(recorded)
    return candidates, record.content_hash


def _input_paths(cfg: EvaluateMdnConfig) -> dict[str, Path]:
    """model, depth and the object dataset depth was rendered from (`objects=`, or the
    one depth's manifest records), checked to be that dataset by its content hash."""
    depth = Path(cfg.depth)
    try:
        candidates, expected = recorded_objects(depth)
    except InputError as err:
        message = str(err)
        raise InputError(message if message.startswith("depth:") else f"depth: {message}") from None
    if cfg.objects is not None:
        objects = Path(cfg.objects)
    else:
        found = [p for p in candidates if (p / MANIFEST).is_file()]
        if not found:
            raise InputError(
                f"objects: the dataset {depth} was rendered from is not at "
                f"{candidates[0]}; pass objects=PATH (its generate-dataset folder)"
            )
        objects = found[0]
    try:
        actual = read_manifest(objects, expected_stage="generate-dataset").content_hash
    except InputError as err:
        raise InputError(f"objects: {err}") from None
    if actual != expected:
        raise InputError(
            f"objects: {objects} is not the dataset {depth} was rendered from (content hash "
            f"{actual[:12]}, depth records {expected[:12]}); pass objects=PATH"
        )
    return {"model": Path(cfg.model), "depth": depth, "objects": objects}


STAGE: Stage[EvaluateMdnConfig] = Stage(
    name="evaluate-mdn",
    conf="evaluate_mdn",
    schema=EvaluateMdnConfig,
    plan=_plan,
    chunk=evaluate_chunk,
    finalize=_finalize,
    inputs={"model": "train-mdn", "depth": "render-depth", "objects": "generate-dataset"},
    input_paths=_input_paths,
)
