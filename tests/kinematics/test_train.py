"""The learning-rate schedule of the supervised trainings (`learning.trainer.learning_rate`)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from artic.kinematics.config import MdnTrainConfig
from artic.learning.trainer import learning_rate


def _cfg(schedule: str, epochs: int = 10) -> MdnTrainConfig:
    return MdnTrainConfig.model_validate(
        {"epochs": epochs, "lr": 1e-3, "schedule": schedule, "min_lr_ratio": 0.01}
    )


def test_constant_schedule_keeps_the_learning_rate():
    cfg = _cfg("constant")
    assert {learning_rate(cfg, p) for p in np.linspace(0, 12, 50)} == {1e-3}


def test_cosine_schedule_decays_from_lr_to_the_floor_monotonically():
    cfg = _cfg("cosine")
    rates = [learning_rate(cfg, p) for p in np.linspace(0, 10, 101)]
    assert rates[0] == pytest.approx(1e-3) and rates[-1] == pytest.approx(1e-5)
    assert all(a > b for a, b in itertools.pairwise(rates))
    assert learning_rate(cfg, 5.0) == pytest.approx(0.5 * (1e-3 + 1e-5))
    assert learning_rate(cfg, 14.0) == pytest.approx(1e-5), "past the budget: the floor"
    assert math.isclose(learning_rate(cfg, 2.5), learning_rate(_cfg("cosine", 20), 5.0))
