"""Section 3.3.1 evaluation: Ours (most-likely estimate), Ours with the `densest`
estimator, Ours with the test-time geometric refinement (issue 19, kinematics/refine.py),
and the three baselines on the test images, per-image errors, and the calibration of the
MDN's intervals."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from numpy.typing import NDArray

from artic.evaluation.kinematics import coverage, kinematic_errors
from artic.kinematics.baselines import IcpBaseline, mean_baseline, nearest_neighbour, nn_features
from artic.kinematics.data import DepthSplit
from artic.kinematics.mdn import densest, marginal_interval, most_likely
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

    def refinement_table(
        self, object_id: NDArray[np.integer]
    ) -> tuple[list[str], list[list[float | int | str]]]:
        """refinement.csv of `evaluate mdn`: header and one row per refined test image
        (its status, the network's and the returned estimate's depth residuals, metres);
        no rows when the refinement did not run."""
        header = ["image", "object_id", "status", "residual_network_m", "residual_refined_m"]
        rows: list[list[float | int | str]] = [
            [i, int(object_id[i]), status, network, refined]
            for i, (status, network, refined) in enumerate(self.refinement)
        ]
        return header, rows

    def refinement_note(self) -> str:
        """The report's line on the refinement: on how many images, the fallback rate."""
        if not self.refinement:
            return ""
        n = len(self.refinement)
        fallback = sum(not status.startswith("refined") for status, _, _ in self.refinement)
        return (
            f"\n{REFINED}: the test-time geometric refinement (docs/kinematics.md) on the "
            f"first {n} test images; it kept the network's estimate (fallback) on {fallback} "
            f"({100 * fallback / n:.1f}%). Per image: refinement.csv.\n"
        )


def evaluate(
    predictor: Predictor,
    train: DepthSplit,
    test: DepthSplit,
    icp: IcpBaseline | None,
    icp_images: int,
    batch_size: int,
    levels: tuple[float, ...],
    refine_images: int = 0,
) -> Evaluation:
    """Every method on `test`; coverage at `levels` and at `CURVE_LEVELS`; the refined
    estimate (`REFINED`) on the first `refine_images` test images of a category the
    refinement supports."""
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
            for lv in all_levels:
                lo, hi = marginal_interval(mix, lv)
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
    if refine_images > 0 and predictor.category in REFINED_CATEGORIES:
        n = min(refine_images, len(test))
        refined = []
        for i, depth_i in enumerate(test.depth_m(slice(0, n))):
            with torch.no_grad():
                mix = predictor.mixture(depth_i)
            r = predictor.refine(mix, depth_i, None, predictions["Ours"][i])
            refined.append(r.label)
            refinement.append((r.status, r.residual_network, r.residual_refined))
        predictions[REFINED] = np.stack(refined)
    columns = list(codec.columns)
    errors = {
        name: kinematic_errors(
            p, test.labels[: len(p)], columns, predictor.dof, predictor.joint_type
        )
        for name, p in predictions.items()
    }
    cover = {lv: np.where(codec.learned, v / len(test), np.nan) for lv, v in inside.items()}
    return Evaluation(predictions, errors, cover, refinement)
