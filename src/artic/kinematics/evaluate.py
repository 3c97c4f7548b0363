"""Section 3.3.1 evaluation: Ours (most-likely estimate), Ours with the `densest`
estimator, and the three baselines on the test images, per-image errors, and the
calibration of the MDN's intervals."""

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

#: nominal levels of the calibration curve
CURVE_LEVELS = tuple(round(0.05 * k, 2) for k in range(1, 20))


@dataclass(frozen=True)
class Evaluation:
    predictions: dict[str, NDArray[np.float64]]  # method -> (N, L) labels ("ICP": first rows)
    errors: dict[str, dict[str, NDArray[np.float64]]]  # method -> metric -> (N,)
    coverage: dict[float, NDArray[np.float64]]  # level -> (L,) fraction inside (NaN: constant)


def evaluate(
    predictor: Predictor,
    train: DepthSplit,
    test: DepthSplit,
    icp: IcpBaseline | None,
    icp_images: int,
    batch_size: int,
    levels: tuple[float, ...],
) -> Evaluation:
    """Every method on `test`; coverage at `levels` and at `CURVE_LEVELS`."""
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
    columns = list(codec.columns)
    errors = {
        name: kinematic_errors(
            p, test.labels[: len(p)], columns, predictor.dof, predictor.joint_type
        )
        for name, p in predictions.items()
    }
    cover = {lv: np.where(codec.learned, v / len(test), np.nan) for lv, v in inside.items()}
    return Evaluation(predictions, errors, cover)
