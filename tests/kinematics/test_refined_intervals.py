"""The refined estimate's intervals (issue 19: interval calibration for the refined
estimate too): normalised split conformal scales of the network's half-widths, fitted on
withheld images (`kinematics.intervals.refined_scales`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from artic.artifacts.depth_dataset import DepthDataset
from artic.evaluation.kinematics import coverage
from artic.kinematics.data import load_split
from artic.kinematics.evaluate import REFINED, evaluate
from artic.kinematics.intervals import refined_interval, refined_scales
from artic.kinematics.predict import Predictor


def _draw(rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    """Estimates whose error grows with the network's half-width, two columns."""
    half = rng.uniform(0.1, 2.0, (n, 2))
    truth = rng.normal(0.0, 1.0, (n, 2))
    estimate = truth + half * rng.standard_t(3, (n, 2)) * np.array([0.3, 1.5])
    return estimate, truth, half


@pytest.mark.parametrize("level", [0.5, 0.9, 0.95])
def test_scales_hold_the_level_on_fresh_images(level):
    rng = np.random.default_rng(0)
    estimate, truth, half = _draw(rng, 2000)
    k = refined_scales(estimate, truth, half, level)
    assert k.shape == (2,) and np.all(k > 0)
    fresh_estimate, fresh_truth, fresh_half = _draw(rng, 50000)
    held = coverage(*refined_interval(fresh_estimate, fresh_half, k), fresh_truth)
    np.testing.assert_allclose(held, level, atol=0.015)
    # and on the images it was fitted on, at least the level (the conformal rank)
    own = coverage(*refined_interval(estimate, half, k), truth)
    assert np.all(own >= level)


def test_too_few_images_for_the_level_give_an_unbounded_interval():
    estimate, truth, half = _draw(np.random.default_rng(1), 9)
    assert np.all(np.isinf(refined_scales(estimate, truth, half, 0.95)))  # ceil(10 x 0.95) > 9
    assert np.all(np.isfinite(refined_scales(estimate, truth, half, 0.9)))


def test_intervals_fitted_on_the_test_images_cover_them(tiny_model, tiny_depth):
    """`evaluate` with its calibration images the refined test images themselves: every
    learned column's coverage at least the level, at every level."""
    predictor = Predictor.load(tiny_model / "model.pt", "microwave")
    ds = DepthDataset.open(tiny_depth)
    train, test = load_split(ds, "train"), load_split(ds, "test")
    result = evaluate(predictor, train, test, None, 0, 8, (0.5, 0.9), refine_images=len(test),
                      calibration=test)  # fmt: skip
    assert REFINED in result.predictions
    assert result.calibration_images == len(test)
    assert f"k per column fitted on {len(test)} validation images" in result.refinement_note((0.9,))
    learned = predictor.codec.learned
    assert set(result.refined_coverage) == set(result.coverage)
    for level, cover in result.refined_coverage.items():
        assert np.all(np.isnan(cover[~learned]))
        need = math.ceil((len(test) + 1) * level)
        inside = cover[learned] * len(test)
        if need <= len(test):
            assert np.all(inside >= need - 1e-9), (level, cover[learned])
        assert np.all(result.refined_scales[level][learned] >= 0)
