"""Section 3.3.1 evaluation: Ours (most-likely estimate), Ours with the `densest`
estimator, Ours with the test-time geometric refinement (issue 19, kinematics/refine.py),
and the three baselines on the test images, per-image errors, and the calibration of the
MDN's intervals and of the refined estimate's (`refined_scales`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from numpy.typing import NDArray

from artic.artifacts.formats import write_csv
from artic.evaluation.kinematics import (
    calibration_groups,
    calibration_rows,
    coverage,
    kinematic_errors,
)
from artic.kinematics.baselines import IcpBaseline, mean_baseline, nearest_neighbour, nn_features
from artic.kinematics.data import DepthSplit
from artic.kinematics.intervals import (
    REFINED_INTERVALS,
    refined_interval,
    refined_scales,
    write_refined_intervals,
)
from artic.kinematics.mdn import densest, marginal_intervals, most_likely
from artic.kinematics.predict import Predictor
from artic.kinematics.preprocess import full_image
from artic.kinematics.refine import SUPPORTED as REFINED_CATEGORIES

#: the method name of the refined estimate in every table
REFINED = "Ours + refinement"

#: nominal levels of the calibration curve
CURVE_LEVELS = tuple(round(0.05 * k, 2) for k in range(1, 20))


@dataclass(frozen=True)
class Evaluation:
    predictions: dict[str, NDArray[np.float64]]  # method -> (N, L) labels ("ICP": first rows)
    errors: dict[str, dict[str, NDArray[np.float64]]]  # method -> metric -> (N,)
    coverage: dict[float, NDArray[np.float64]]  # level -> (L,) fraction inside (NaN: constant)
    #: per refined image (the first rows): status, network's and returned residual (m)
    refinement: list[tuple[str, float, float]]
    #: the refined estimate's intervals (`refined_scales`): level -> (L,) scale k of the
    #: network's half-width, and level -> (L,) fraction of the refined test images inside
    refined_scales: dict[float, NDArray[np.float64]] = field(default_factory=dict)
    refined_coverage: dict[float, NDArray[np.float64]] = field(default_factory=dict)
    #: how many validation images `refined_scales` were fitted on
    calibration_images: int = 0

    def write_refinement(
        self, folder: Path, object_id: NDArray[np.integer], columns: list[str], dof: int
    ) -> None:
        """The refinement's files of `evaluate mdn` in `folder`: refinement.csv (one row
        per refined test image: its status, the network's and the returned estimate's
        depth residuals, metres; no rows when the refinement did not run) and, when its
        intervals were fitted, calibration_refined.csv and refined_intervals.csv."""
        header = ["image", "object_id", "status", "residual_network_m", "residual_refined_m"]
        rows: list[list[float | int | str]] = [
            [i, int(object_id[i]), status, network, refined]
            for i, (status, network, refined) in enumerate(self.refinement)
        ]
        write_csv(folder / "refinement.csv", header, rows)
        if self.refined_coverage:
            groups = calibration_groups(columns, dof)
            calibration = calibration_rows(self.refined_coverage, groups)
            write_csv(folder / "calibration_refined.csv", ["nominal", *groups], calibration)
            write_refined_intervals(folder / REFINED_INTERVALS, columns, self.refined_scales)

    def refinement_note(self, levels: tuple[float, ...] = ()) -> str:
        """The report's lines on the refinement: on how many images, the fallback rate,
        and the coverage of its intervals at `levels` (over all predicted columns)."""
        if not self.refinement:
            return ""
        n = len(self.refinement)
        fallback = sum(not status.startswith("refined") for status, _, _ in self.refinement)
        note = (
            f"\n{REFINED}: the test-time geometric refinement (docs/kinematics.md) on the "
            f"first {n} test images; it kept the network's estimate (fallback) on {fallback} "
            f"({100 * fallback / n:.1f}%). Per image: refinement.csv.\n"
        )
        shown = [lv for lv in levels if lv in self.refined_coverage]
        if not self.refined_coverage:
            note += "No validation images to fit its intervals on: none reported.\n"
        elif shown:
            cells = ", ".join(
                f"{100 * lv:.0f}%: {100 * float(np.nanmean(self.refined_coverage[lv])):.1f}%"
                for lv in shown
            )
            note += (
                f"Its intervals (the estimate +- k x the network's half-width, k per column "
                f"fitted on {self.calibration_images} validation images: refined_intervals.csv) "
                f"held the truth in {cells} (all predicted columns; calibration_refined.csv).\n"
            )
        return note


def evaluate(
    predictor: Predictor,
    train: DepthSplit,
    test: DepthSplit,
    icp: IcpBaseline | None,
    icp_images: int,
    batch_size: int,
    levels: tuple[float, ...],
    refine_images: int = 0,
    calibration: DepthSplit | None = None,
) -> Evaluation:
    """Every method on `test`; coverage at `levels` and at `CURVE_LEVELS`; the refined
    estimate (`REFINED`) on the first `refine_images` test images of a category the
    refinement supports, with its intervals' scales fitted on the first `refine_images`
    images of `calibration` (withheld from training: the validation split's first
    `evaluate.calibration_images`, as the CLI passes it; `refined_scales`) and their
    coverage on the refined test images."""
    codec = predictor.codec
    all_levels = tuple(sorted(set(levels) | set(CURVE_LEVELS)))
    inside = {lv: np.zeros(len(codec.columns)) for lv in all_levels}
    ours, ours_densest, test_features = [], [], []
    inputs = predictor.inputs
    with torch.no_grad():
        for start in range(0, len(test), batch_size):
            index = slice(start, start + batch_size)
            depth = test.depth_m(index)
            mix = predictor.model(*inputs(depth))
            ours.append(codec.decode(most_likely(mix).numpy()))
            ours_densest.append(codec.decode(densest(mix).numpy()))
            truth = test.labels[index]
            for lv, (lo, hi) in marginal_intervals(mix, all_levels).items():
                c = coverage(codec.decode(lo.numpy()), codec.decode(hi.numpy()), truth)
                inside[lv] += c * len(truth)
            test_features.append(nn_features(full_image(depth)))
        train_features = torch.cat(
            [
                nn_features(full_image(train.depth_m(slice(s, s + 1024))))
                for s in range(0, len(train), 1024)
            ]
        )
    queries = torch.cat(test_features)
    nn = np.concatenate([
        nearest_neighbour(train_features, train.labels, queries[s : s + 256])
        for s in range(0, len(queries), 256)
    ])  # fmt: skip
    predictions = {
        "Mean": mean_baseline(train.labels, len(test)),
        "NN": nn,
        "Ours": np.concatenate(ours),
        "Ours (densest)": np.concatenate(ours_densest),
    }
    if icp is not None and icp_images > 0:
        n = min(icp_images, len(test))
        predictions["ICP"] = np.stack([icp.predict(d) for d in test.depth_m(slice(0, n))])
    refinement: list[tuple[str, float, float]] = []
    scales: dict[float, NDArray[np.float64]] = {}
    refined_cover: dict[float, NDArray[np.float64]] = {}
    held_images = 0
    if refine_images > 0 and predictor.category in REFINED_CATEGORIES:
        n = min(refine_images, len(test))
        refined, halves = _refined(predictor, test.depth_m(slice(0, n)), all_levels, refinement)
        predictions[REFINED] = refined
        if calibration is not None and len(calibration) > 0:
            held = calibration.head(refine_images)
            held_images = len(held)
            fitted, fitted_halves = _refined(predictor, held.depth_m(slice(0, len(held))),
                                             all_levels, [])  # fmt: skip
            for lv in all_levels:
                k = refined_scales(fitted, held.labels, fitted_halves[lv], lv)
                scales[lv] = np.where(codec.learned, k, np.nan)
                c = coverage(*refined_interval(refined, halves[lv], k), test.labels[:n])
                refined_cover[lv] = np.where(codec.learned, c, np.nan)
    columns = list(codec.columns)
    errors = {
        name: kinematic_errors(
            p, test.labels[: len(p)], columns, predictor.dof, predictor.joint_type
        )
        for name, p in predictions.items()
    }
    cover = {lv: np.where(codec.learned, v / len(test), np.nan) for lv, v in inside.items()}
    return Evaluation(predictions, errors, cover, refinement, scales, refined_cover, held_images)


def _refined(
    predictor: Predictor,
    depth: NDArray[np.float32],
    levels: tuple[float, ...],
    record: list[tuple[str, float, float]],
) -> tuple[NDArray[np.float64], dict[float, NDArray[np.float64]]]:
    """The refined estimates (N, L) of the images `depth` (N, H, W), one image at a time
    as `artic predict` refines (from the network's most likely estimate of the image),
    and, per level, the half-widths (N, L) of the network's central intervals; each
    refinement's status and residuals appended to `record`."""
    refined: list[NDArray[np.float64]] = []
    halves: dict[float, list[NDArray[np.float64]]] = {lv: [] for lv in levels}
    for depth_i in depth:
        with torch.no_grad():
            mix = predictor.mixture(depth_i)
        label = predictor._estimate(mix, depth_i, None, "most-likely")
        r = predictor.refine(mix, depth_i, None, label)
        refined.append(r.label)
        record.append((r.status, r.residual_network, r.residual_refined))
        for lv, (lo, hi) in marginal_intervals(mix, levels).items():
            halves[lv].append(0.5 * (predictor.codec.decode(hi.numpy())[0]
                                     - predictor.codec.decode(lo.numpy())[0]))  # fmt: skip
    return np.stack(refined), {lv: np.stack(h) for lv, h in halves.items()}
