"""The Table 3.1 baselines: the ICP registration to the class's mean model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from artic.evaluation.kinematics import kinematic_errors
from artic.geometry.camera import CameraIntrinsics
from artic.kinematics.baselines import ICP_INITS, IcpBaseline
from artic.objects.categories import build
from artic.objects.labels import image_labels, label_columns
from artic.objects.spec import CategoryConfig, sample_spec
from artic.render.raycast import RaycastBackend

CONF = Path(__file__).resolve().parents[2] / "conf" / "common" / "category"
CAMERA = CameraIntrinsics(fx=140.0, fy=140.0, cx=63.5, cy=63.5, width=128, height=128)


def _training_set(category: str, n: int) -> tuple[CategoryConfig, np.ndarray]:
    cfg = CategoryConfig.model_validate(yaml.safe_load((CONF / f"{category}.yaml").read_text()))
    rng = np.random.default_rng(0)
    rows = []
    for i in range(n):
        spec = sample_spec(cfg, CAMERA, i, rng)
        q = rng.uniform(*spec.joint_limits[0], size=spec.dof)
        rows.append(list(image_labels(spec, build(spec), q).values()))
    return cfg, np.array(rows)


@pytest.mark.parametrize("turn_deg", [-30.0, 25.0])
def test_icp_recovers_the_yaw_of_the_mean_model_turned_within_the_prior(turn_deg: float) -> None:
    cfg, train = _training_set("microwave", 40)
    template = sample_spec(cfg, CAMERA, 0, np.random.default_rng(1))
    icp = IcpBaseline(template, train, CAMERA)
    columns = label_columns(template.dof)
    col = {c: i for i, c in enumerate(columns)}
    view_yaws = [labels[col["pose_yaw"]] for _, labels in icp.views]
    assert len(icp.views) == ICP_INITS  # the mean model in 16 poses spanning the yaws
    assert np.ptp(view_yaws) == pytest.approx(np.ptp(train[:, col["pose_yaw"]]))

    # the mean model, turned about its base origin: ICP must find the turn
    mean = train.mean(axis=0)
    turned = mean.copy()
    turned[col["pose_yaw"]] += np.radians(turn_deg)
    spec = template.model_copy(
        update={
            **{k: float(mean[col[k]]) for k in ("depth", "width", "height")},
            "chirality": 1,
            "pose": template.pose.model_copy(
                update={k: float(turned[col[f"pose_{k}"]]) for k in ("x", "y", "z", "yaw")}
            ),
        }
    )
    q = np.array([mean[col["j0_q"]]])
    truth = np.array(list(image_labels(spec, build(spec), q).values()))
    depth = RaycastBackend(CAMERA).render(build(spec), q).depth
    pred = icp.predict(depth)
    errors = kinematic_errors(pred[None], truth[None], columns, 1, template.joint_type)
    assert errors["rotation_deg"][0] < 5.0
    assert errors["position_cm"][0] < 5.0
    # the middle pose is well off: the test can fail
    before = kinematic_errors(icp.labels[None], truth[None], columns, 1, template.joint_type)
    assert before["rotation_deg"][0] > 15.0
