"""Table 3.1 errors: the yaw error, the thesis' clamped-quaternion rotation metric and the
hinge side."""

import numpy as np
import pytest

from artic.evaluation.kinematics import kinematic_errors, thesis_axis_angle

COLUMNS = ["pose_yaw", "chirality", "j0_q", "j0_origin_x", "j0_origin_y", "j0_origin_z"]


def _labels(yaw: np.ndarray) -> np.ndarray:
    out = np.zeros((len(yaw), len(COLUMNS)))
    out[:, 0] = yaw
    return out


def test_thesis_axis_angle_saturates_on_one_side_of_facing_the_camera():
    yaw = np.array([-np.pi / 4, -0.1, 0.0, 0.1, np.pi / 4])
    np.testing.assert_allclose(
        thesis_axis_angle(yaw), [3 * np.pi / 4, np.pi - 0.1, np.pi, np.pi, np.pi], atol=1e-12
    )


def test_thesis_metric_halves_a_mean_predictors_error_and_is_zero_when_exact():
    yaw = np.random.default_rng(0).uniform(-np.pi / 4, np.pi / 4, 20000)
    true = _labels(yaw)
    mean = _labels(np.zeros_like(yaw))
    e = kinematic_errors(mean, true, COLUMNS, 1, "revolute")
    assert e["rotation_deg"].mean() == pytest.approx(22.5, abs=0.3)
    assert e["rotation_thesis_deg"].mean() == pytest.approx(11.25, abs=0.3)
    exact = kinematic_errors(true, true, COLUMNS, 1, "revolute")
    assert exact["rotation_thesis_deg"].max() == 0.0 and exact["rotation_deg"].max() == 0.0
    # both yaws > 0: the thesis' metric sees no error at all; both < 0: the yaw error
    both = kinematic_errors(_labels(np.array([0.1, -0.1])), _labels(np.array([0.5, -0.5])),
                            COLUMNS, 1, "revolute")  # fmt: skip
    np.testing.assert_allclose(both["rotation_thesis_deg"], [0.0, np.degrees(0.4)], atol=1e-9)
    np.testing.assert_allclose(both["rotation_deg"], np.degrees([0.4, 0.4]), atol=1e-9)


def test_hinge_side_is_wrong_exactly_where_the_chirality_signs_differ():
    true = _labels(np.zeros(4))
    true[:, 1] = [1.0, 1.0, -1.0, -1.0]
    pred = _labels(np.zeros(4))
    pred[:, 1] = [0.3, -0.2, -0.9, 0.0]  # a chirality of 0 reads as +1 (`Predictor`)
    e = kinematic_errors(pred, true, COLUMNS, 1, "revolute")
    np.testing.assert_array_equal(e["hinge_side_wrong_pct"], [0.0, 100.0, 0.0, 100.0])
