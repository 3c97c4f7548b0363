"""The baselines of Table 3.1 (section 3.3.1), each mapping test images to label vectors.

- Mean: the training set's mean label vector, for every image.
- NN: the label of the nearest training image in depth-image space. Images are compared
  as network inputs (depth / 4 m, 0 = no return) area-averaged to 32x32, by Euclidean
  distance (over the full image it picks the same neighbours in our tests at 16x the
  cost; the thesis does not give its resolution).
- ICP: the observed cloud registered to the class's mean model (mean geometry, position
  and configuration, chirality +1) in 16 poses, with yaws spread evenly over the training
  set's yaw range (the class's pose prior, from the training set as Mean and NN are).
  Each pose is the cloud the camera sees of it (raycast, 2 cm voxels); point-to-point
  ICP (Open3D) from the centroids' offset; the best fit (highest fitness, then lowest
  RMSE) moves that pose's axes and base. ICP is rigid: configuration and size stay the
  mean's.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from numpy.typing import NDArray

from artic.evaluation.kinematics import wrap_angle
from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import make_transform
from artic.objects.categories import build
from artic.objects.labels import image_labels, joint_column, joint_vector, label_columns
from artic.objects.spec import ObjectSpec, Pose

NN_SIZE = 32
ICP_INITS = 16
MIN_POINTS = 10


def mean_baseline(train_labels: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """(n, L): the mean training label for each of n images."""
    return np.repeat(train_labels.mean(axis=0, keepdims=True), n, axis=0)


def nn_features(inputs: torch.Tensor) -> torch.Tensor:
    """Network inputs (N, 1, H, W) -> (N, NN_SIZE^2) area-averaged descriptors."""
    return F.adaptive_avg_pool2d(inputs, NN_SIZE).flatten(1)


def nearest_neighbour(
    train_features: torch.Tensor, train_labels: NDArray[np.float64], query: torch.Tensor
) -> NDArray[np.float64]:
    """(Q, L): the label of the nearest training descriptor of each query descriptor."""
    d2 = (
        query.square().sum(1, keepdim=True)
        - 2 * query @ train_features.T
        + train_features.square().sum(1)[None]
    )
    return train_labels[d2.argmin(dim=1).numpy()]


class IcpBaseline:
    """Registration of observed clouds to the category's mean model, built from the
    training labels (N, L): their mean is the model (mean geometry, position and
    configuration, chirality +1), shown in ICP_INITS poses whose yaws span the training
    yaws. Each pose is the cloud the training camera sees of it, so the observed cloud is
    matched to views of the model, not to the model's hidden faces."""

    def __init__(
        self,
        template: ObjectSpec,
        train_labels: NDArray[np.float64],
        camera: CameraIntrinsics,
        voxel_m: float = 0.02,
        max_distance_m: float = 0.1,
    ) -> None:
        from artic.render.open3d_core import open3d_core
        from artic.render.raycast import RaycastBackend

        o3d = open3d_core()
        columns = label_columns(template.dof)
        col = {c: i for i, c in enumerate(columns)}
        mean = train_labels.mean(axis=0)
        dims = {k: float(mean[col[k]]) for k in ("depth", "width", "height")}
        xyz = {k: float(mean[col[f"pose_{k}"]]) for k in ("x", "y", "z")}
        q = np.array([mean[col[joint_column(j, "q")]] for j in range(template.dof)])
        yaws = train_labels[:, col["pose_yaw"]]
        renderer = RaycastBackend(camera)
        self.columns = columns
        self.views: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
        for yaw in np.linspace(yaws.min(), yaws.max(), ICP_INITS):
            pose = Pose(**xyz, yaw=float(yaw))
            spec = template.model_copy(update={**dims, "pose": pose, "chirality": 1})
            obj = build(spec)
            view = _down_sample(camera.back_project(renderer.render(obj, q).depth), voxel_m)
            if len(view) >= MIN_POINTS:
                self.views.append((view, np.array(list(image_labels(spec, obj, q).values()))))
        if not self.views:
            raise ValueError("ICP: the mean model is out of the camera's view in every pose")
        self.labels = self.views[len(self.views) // 2][1]  # the middle pose: too few points
        # the registration targets, built once
        self._targets = [
            o3d.geometry.PointCloud(o3d.utility.Vector3dVector(v)) for v, _ in self.views
        ]
        self.camera, self.voxel, self.max_distance = camera, voxel_m, max_distance_m

    def predict(self, depth: NDArray[np.float32]) -> NDArray[np.float64]:
        """(L,) labels of one depth image (training camera).

        Open3D's ICP sums over points in OpenMP threads, in an order that depends on
        their number; it runs on one thread, so the result does not depend on the machine.
        """
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="openmp"):
            return self._predict(depth)

    def _predict(self, depth: NDArray[np.float32]) -> NDArray[np.float64]:
        from artic.render.open3d_core import open3d_core

        o3d = open3d_core()

        reg = o3d.pipelines.registration
        points = _down_sample(self.camera.back_project(depth), self.voxel)
        if len(points) < MIN_POINTS:
            return self.labels.copy()
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        best: tuple[tuple[float, float], NDArray[np.float64], NDArray[np.float64]] | None = None
        for (view, labels), target in zip(self.views, self._targets, strict=True):
            # observed -> model view, starting from the centroids' offset
            init = make_transform(translation=view.mean(axis=0) - points.mean(axis=0))
            fit = reg.registration_icp(
                cloud, target, self.max_distance, init,
                reg.TransformationEstimationPointToPoint(),
                reg.ICPConvergenceCriteria(max_iteration=30),
            )  # fmt: skip
            score = (fit.fitness, -fit.inlier_rmse)
            if best is None or score > best[0]:
                best = (score, np.asarray(fit.transformation), labels)
        assert best is not None
        view_to_observed = np.asarray(np.linalg.inv(best[1]), dtype=np.float64)
        return relabel_rigid(best[2], self.columns, view_to_observed)


def _down_sample(points: NDArray[np.float64], voxel_m: float) -> NDArray[np.float64]:
    from artic.render.open3d_core import open3d_core

    o3d = open3d_core()

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    return np.asarray(cloud.voxel_down_sample(voxel_m).points)


def relabel_rigid(
    labels: NDArray[np.float64], columns: list[str], motion: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The labels of the object moved by the (4, 4) camera-frame `motion`: base position,
    axis origins and directions move with it, the yaw changes by the motion's rotation
    about z; configuration, size and part origins (in the axis frame) do not change."""
    col = {c: i for i, c in enumerate(columns)}
    out = labels.copy()
    rotation, translation = motion[:3, :3], motion[:3, 3]
    base = [col[f"pose_{a}"] for a in "xyz"]
    out[base] = rotation @ labels[base] + translation
    turn = np.arctan2(rotation[1, 0], rotation[0, 0])
    out[col["pose_yaw"]] = float(wrap_angle(np.array(labels[col["pose_yaw"]] + turn)))
    j = 0
    while joint_column(j, "origin_x") in col:
        o = [col[c] for c in joint_vector(j, "origin")]
        d = [col[c] for c in joint_vector(j, "direction")]
        out[o] = rotation @ labels[o] + translation
        out[d] = rotation @ labels[d]
        j += 1
    return out
