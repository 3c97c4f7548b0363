"""Depth from PyBullet's TinyRenderer (CPU rasteriser) over the object's URDF.

The projection matrix is built from the full pinhole intrinsics (off-centre principal
points included). TinyRenderer samples image pixel (u, v) (v counted from the top) at
OpenGL window coordinates (u, height - 1 - v), not at pixel centres (u + 0.5, ...):
measured on slanted planes, where a half-pixel error shows as a depth offset of half
the depth gradient; with this convention both backends agree to 1e-5 m. One DIRECT
client per backend.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from artic.geometry.camera import CameraIntrinsics
from artic.objects.model import ArticulatedObject
from artic.render.backend import BackendBase, RenderedImage, register_backend
from artic.sim.bullet import connect_direct, pybullet_module

pybullet = pybullet_module()


def projection_matrix(camera: CameraIntrinsics, near: float, far: float) -> NDArray[np.float64]:
    """(4, 4) OpenGL projection (eye looks down -z, y up) that puts camera-frame points on
    the pixels `CameraIntrinsics.project` gives, under TinyRenderer's sampling."""
    w, h = camera.width, camera.height
    return np.array(
        [
            [2 * camera.fx / w, 0.0, 1.0 - 2 * camera.cx / w, 0.0],
            [0.0, 2 * camera.fy / h, 2 * (camera.cy + 1.0) / h - 1.0, 0.0],
            [0.0, 0.0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0.0, 0.0, -1.0, 0.0],
        ]
    )


def view_matrix() -> NDArray[np.float64]:
    """(4, 4) world -> eye for the thesis camera: forward +x, up +z, right -y."""
    return np.array(
        [[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    )


@register_backend("pybullet")
class PyBulletBackend(BackendBase):
    """TinyRenderer; the URDF is loaded once and re-posed for each configuration."""

    def __init__(
        self, camera: CameraIntrinsics, threads: int = 1, near: float = 0.05, far: float = 20.0
    ) -> None:
        self.camera = camera
        self.near, self.far = near, far
        self._client: Any = connect_direct()
        # PyBullet takes column-major flat lists
        self._view = view_matrix().T.reshape(-1).tolist()
        self._proj = projection_matrix(camera, near, far).T.reshape(-1).tolist()
        self._body: int | None = None
        self._path: Path | None = None
        self._joints: dict[str, int] = {}

    def _load(self, urdf_path: Path, obj: ArticulatedObject) -> int:
        client = self._require_client()
        if self._body is not None and self._path == urdf_path:
            return self._body
        if self._body is not None:
            client.removeBody(self._body)
        pose = obj.base_pose
        quat = Rotation.from_matrix(pose[:3, :3]).as_quat()  # x, y, z, w
        body = client.loadURDF(
            str(urdf_path),
            basePosition=pose[:3, 3].tolist(),
            baseOrientation=quat.tolist(),
            useFixedBase=True,
        )
        self._joints = {
            client.getJointInfo(body, j)[1].decode(): j for j in range(client.getNumJoints(body))
        }
        self._body, self._path = body, urdf_path
        return body

    def _require_client(self) -> Any:
        if self._client is None:
            raise RuntimeError("the pybullet backend is closed")
        return self._client

    def render(
        self,
        obj: ArticulatedObject,
        configuration: NDArray[np.float64],
        urdf_path: Path | None = None,
    ) -> RenderedImage:
        if urdf_path is None:
            raise ValueError("the pybullet backend renders URDF files: pass urdf_path")
        client = self._require_client()
        body = self._load(urdf_path, obj)
        q = np.asarray(configuration, dtype=np.float64).reshape(-1)
        for joint, value in zip(obj.movable_joints, q, strict=True):
            client.resetJointState(body, self._joints[joint.name], float(value))
        w, h = self.camera.width, self.camera.height
        _, _, _, zbuf, seg = client.getCameraImage(
            w,
            h,
            viewMatrix=self._view,
            projectionMatrix=self._proj,
            renderer=pybullet.ER_TINY_RENDERER,
            flags=pybullet.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX,
        )
        z = np.asarray(zbuf, dtype=np.float64).reshape(h, w)
        segment = np.asarray(seg, dtype=np.int64).reshape(h, w)
        hit = (segment >= 0) & (z < 1.0)
        metres = self.far * self.near / (self.far - (self.far - self.near) * z)
        depth = np.where(hit, metres, 0.0).astype(np.float32)
        link = (segment >> 24) - 1  # -1 = base = part 0
        mask = np.where(hit, link + 2, 0).astype(np.uint8)
        return RenderedImage(depth, mask)

    def close(self) -> None:
        if self._client is not None:
            self._client.disconnect()
            self._client = None
