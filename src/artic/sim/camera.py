"""A camera on a Chapter 5 task: RGB frames of the robot and the object, and animated GIFs.

`SceneCamera(world, cfg)` draws a `TaskWorld` with PyBullet's TinyRenderer (a CPU
rasteriser: no GPU, no display, the same pixels on every run) in a DIRECT client of its
own. That client holds visual copies of the scene: the ground, the iiwa (its URDF's
meshes), the object's links as visual meshes (the simulation builds them as collision
shapes only, which TinyRenderer does not draw) or the tee and the ball. Before each frame
the copies are posed from what the world reports (`robot_q`, `object_q` through the true
kinematic model, `ball_position`). The simulation client is only read, never rendered
into or stepped, so an episode gives the same trajectory, bit for bit, with or without a
camera.

View: PyBullet's orbit camera (`computeViewMatrixFromYawPitchRoll`, z up) around `target`,
a perspective of `fov_deg` vertical field of view; `CameraConfig`'s defaults frame the
robot and the objects of all three tasks. Frames: (height, width, 3) uint8 RGB.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.config.schemas import Strict

if TYPE_CHECKING:
    from artic.sim.world import TaskWorld

#: RGBA of object links by role (Appendix A's parts); other roles get `_OTHER`
_COLOURS = {
    "body": (0.80, 0.72, 0.58, 1.0),
    "drawer": (0.93, 0.88, 0.78, 1.0),
    "door": (0.70, 0.78, 0.86, 1.0),
    "handle": (0.25, 0.25, 0.28, 1.0),
}
_OTHER = (0.75, 0.75, 0.75, 1.0)
_BALL = (0.95, 0.45, 0.1, 1.0)


class CameraConfig(Strict):
    """Where the camera looks from and the image size (`SceneCamera`)."""

    width: int = Field(320, ge=16, le=1920, description="image width, pixels")
    height: int = Field(240, ge=16, le=1080, description="image height, pixels")
    fov_deg: float = Field(50.0, gt=0, lt=180, description="vertical field of view, degrees")
    target: tuple[float, float, float] = Field(
        (0.6, 0.2, 0.3), description="point the camera looks at (world frame), m"
    )
    distance: float = Field(2.4, gt=0, description="camera distance from the target, m")
    yaw_deg: float = Field(
        -130.0, description="camera azimuth about world z, degrees (PyBullet orbit camera)"
    )
    pitch_deg: float = Field(-35.0, ge=-89, le=89, description="camera elevation, degrees")


class SceneCamera:
    """Renders a `TaskWorld` (see the module docstring); `close()` frees its client."""

    def __init__(self, world: TaskWorld, cfg: CameraConfig | None = None) -> None:
        from artic.sim.bullet import connect_direct
        from artic.sim.robot import Robot
        from artic.sim.scene import load_ground, load_tball
        from artic.sim.tasks import TBallScene

        self.world = world
        self.cfg = cfg or CameraConfig()
        self._client: Any = connect_direct()
        client = self._client
        task = world.cfg
        load_ground(client)
        self._robot = Robot.load(client, task.robot)
        self._ball: int | None = None
        self._links: list[int] = []
        if isinstance(task.scene, TBallScene):
            self._ball = load_tball(client, task.scene).ball
            client.changeVisualShape(self._ball, -1, rgbaColor=list(_BALL))
        else:
            self._model = world.kinematic_model()
            for link in self._model.links:
                self._links.append(-1 if link.mesh.is_empty else self._visual_body(link))
        c = self.cfg
        self._view = client.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=list(c.target),
            distance=c.distance,
            yaw=c.yaw_deg,
            pitch=c.pitch_deg,
            roll=0.0,
            upAxisIndex=2,
        )
        self._projection = client.computeProjectionMatrixFOV(
            fov=c.fov_deg, aspect=c.width / c.height, nearVal=0.05, farVal=20.0
        )

    def _visual_body(self, link: Any) -> int:
        client = self._client
        shape = client.createVisualShape(
            client.GEOM_MESH,
            vertices=np.asarray(link.mesh.vertices, dtype=np.float64).tolist(),
            indices=np.asarray(link.mesh.triangles, dtype=np.int64).reshape(-1).tolist(),
            rgbaColor=list(_COLOURS.get(link.role, _OTHER)),
        )
        return int(client.createMultiBody(baseMass=0.0, baseVisualShapeIndex=shape))

    def _pose_scene(self) -> None:
        from artic.sim.robot import pose_to_pybullet

        client = self._client
        self._robot.set_state(self.world.robot_q())
        if self._ball is not None:
            ball = self.world.ball_position()
            assert ball is not None
            client.resetBasePositionAndOrientation(self._ball, ball.tolist(), [0, 0, 0, 1])
            return
        poses = self._model.link_poses(self.world.object_q())
        for body, pose in zip(self._links, poses, strict=True):
            if body >= 0:
                position, quaternion = pose_to_pybullet(pose)
                client.resetBasePositionAndOrientation(body, position, quaternion)

    def render(self) -> NDArray[np.uint8]:
        """(height, width, 3) uint8 RGB image of the world as it is now."""
        if self._client is None:
            raise RuntimeError("the camera is closed")
        self._pose_scene()
        c = self.cfg
        _, _, rgba, _, _ = self._client.getCameraImage(
            c.width,
            c.height,
            viewMatrix=self._view,
            projectionMatrix=self._projection,
            renderer=self._client.ER_TINY_RENDERER,
            shadow=0,
            lightDirection=[1.0, 1.0, 2.0],
        )
        image = np.asarray(rgba, dtype=np.uint8).reshape(c.height, c.width, 4)
        return np.ascontiguousarray(image[:, :, :3])

    def close(self) -> None:
        """Disconnect the camera's client (idempotent)."""
        if self._client is not None:
            self._client.disconnect()
            self._client = None


def encode_gif(frames: Sequence[NDArray[np.uint8]], fps: float) -> bytes:
    """An animated GIF (Pillow) of `frames`, each (H, W, 3) uint8, shown at `fps` frames
    per second and looped. The same frames give the same bytes. GIF stores delays in
    hundredths of a second, so the delay is rounded to 10 ms."""
    from PIL import Image

    if not frames:
        raise ValueError("encode_gif needs at least one frame")
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    buffer = io.BytesIO()
    images[0].save(
        buffer,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(20, round(1000.0 / fps / 10.0) * 10),
        loop=0,
    )
    return buffer.getvalue()
