"""The baselines of Table 3.1 (section 3.3.1), each mapping test images to label vectors.

- Mean: the training set's mean label vector, for every image.
- NN: the label of the nearest training image in depth-image space. Images are compared
  as network inputs (depth / 4 m, 0 = no return) area-averaged to 32x32, by Euclidean
  distance (over the full image it picks the same neighbours in our tests at 16x the
  cost; the thesis does not give its resolution).
- ICP: the observed cloud registered to the class's mean model (mean geometry and pose,
  mean configuration, chirality +1), from 16 initial yaws about the cloud's centroid
  (point-to-point ICP, Open3D); the best fit (highest fitness, then lowest RMSE) moves
  the mean model's axes and pose. ICP is rigid: configuration and size stay the mean's.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from numpy.typing import NDArray

from artic.evaluation.kinematics import wrap_angle
from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import make_transform, rot_z, transform_points
from artic.objects.categories import build
from artic.objects.labels import image_labels, label_columns
from artic.objects.spec import ObjectSpec, Pose

NN_SIZE = 32
ICP_INITS = 16


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
    """Registration of observed clouds to the category's mean model."""

    def __init__(
        self,
        template: ObjectSpec,
        mean_labels: NDArray[np.float64],
        camera: CameraIntrinsics,
        voxel_m: float = 0.02,
        max_distance_m: float = 0.1,
        seed: int = 0,
    ) -> None:
        import open3d as o3d

        columns = label_columns(template.dof)
        col = {c: i for i, c in enumerate(columns)}
        pose = Pose(**{k: float(mean_labels[col[f"pose_{k}"]]) for k in ("x", "y", "z", "yaw")})
        dims = {k: float(mean_labels[col[k]]) for k in ("depth", "width", "height")}
        spec = template.model_copy(update={**dims, "pose": pose, "chirality": 1})
        q = np.array([mean_labels[col[f"j{j}_q"]] for j in range(template.dof)])
        obj = build(spec)
        self.labels = np.array(list(image_labels(spec, obj, q).values()))
        self.columns = columns
        mesh = o3d.geometry.TriangleMesh()
        for link, link_pose in zip(obj.links, obj.link_poses(q), strict=True):
            part = o3d.geometry.TriangleMesh(
                o3d.utility.Vector3dVector(transform_points(link_pose, link.mesh.vertices)),
                o3d.utility.Vector3iVector(link.mesh.triangles.astype(np.int32)),
            )
            mesh += part
        o3d.utility.random.seed(seed)
        self._model = mesh.sample_points_uniformly(4000)
        self.camera, self.voxel, self.max_distance = camera, voxel_m, max_distance_m

    def predict(self, depth: NDArray[np.float32]) -> NDArray[np.float64]:
        """(L,) labels of one depth image (training camera)."""
        import open3d as o3d

        reg = o3d.pipelines.registration
        points = self.camera.back_project(depth)
        if len(points) < 10:
            return self.labels.copy()
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        cloud = cloud.voxel_down_sample(self.voxel)
        centre = np.asarray(cloud.points).mean(axis=0)
        model_centre = np.asarray(self._model.points).mean(axis=0)
        best = None
        for k in range(ICP_INITS):
            # observed -> model: centre on the model's centroid, turned by yaw k
            turn = make_transform(rotation=rot_z(2 * np.pi * k / ICP_INITS))
            init = make_transform(translation=model_centre) @ turn
            init = init @ make_transform(translation=-centre)
            fit = reg.registration_icp(
                cloud, self._model, self.max_distance, init,
                reg.TransformationEstimationPointToPoint(),
                reg.ICPConvergenceCriteria(max_iteration=30),
            )  # fmt: skip
            if best is None or (fit.fitness, -fit.inlier_rmse) > (best.fitness, -best.inlier_rmse):
                best = fit
        assert best is not None
        model_to_observed = np.linalg.inv(np.asarray(best.transformation))
        return relabel_rigid(self.labels, self.columns, model_to_observed)


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
    while f"j{j}_origin_x" in col:
        o = [col[f"j{j}_origin_{a}"] for a in "xyz"]
        d = [col[f"j{j}_direction_{a}"] for a in "xyz"]
        out[o] = rotation @ labels[o] + translation
        out[d] = rotation @ labels[d]
        j += 1
    return out
