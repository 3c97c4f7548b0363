"""`TaskWorld`: one Chapter 5 task simulated in PyBullet (section 5.3.1).

A world owns two DIRECT clients, each with the same scene (ground plane, the iiwa,
the object or the tee and ball):
- the simulation client, stepped by `apply_action` + `step`;
- a query client that is never stepped, where `ee_pose(q)`, `ik` and `in_collision`
  move the robot and object kinematically, so queries never disturb the simulation.

Determinism: right after building, the simulation client's state is saved
(`saveState`); `reset` restores it and then resets the joints kinematically, so the
same command sequence after a reset gives the same trajectory, bit for bit, whatever
happened before (PyBullet is deterministic given the command sequence).
"""

from __future__ import annotations

from types import TracebackType
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError
from artic.objects.categories import build
from artic.objects.model import ArticulatedObject
from artic.objects.spec import Pose
from artic.sim.bullet import connect_direct
from artic.sim.robot import N_JOINTS, Grasp, IKSettings, Robot, RobotLimits, solve_ik
from artic.sim.scene import (
    ball_start,
    handle_grasp_point,
    load_articulated,
    load_ground,
    load_tball,
    tball_model,
)
from artic.sim.tasks import ArticulatedScene, TaskConfig, TBallScene


class _Bodies(NamedTuple):
    """PyBullet ids of one client's scene; `ball` is None for articulated scenes."""

    robot: Robot
    ground: int
    target: int  # the articulated object, or the tee
    ball: int | None


def sample_scene(scene: ArticulatedScene, rng: np.random.Generator | None) -> ArticulatedScene:
    """The scene with depth, width and height scaled by independent uniforms in
    [1 - jitter, 1 + jitter] drawn from `rng` (`scene.geometry_jitter`; 0 or no rng:
    unchanged), keeping the front face and the base height where they were."""
    if rng is None or scene.geometry_jitter == 0.0:
        return scene
    scale = rng.uniform(1.0 - scene.geometry_jitter, 1.0 + scene.geometry_jitter, size=3)
    depth, width, height = scale * np.array([scene.depth, scene.width, scene.height])
    pose = scene.pose
    shift = 0.5 * (depth - scene.depth)  # keep the front face in place
    moved = Pose(
        x=pose.x + shift * np.cos(pose.yaw),
        y=pose.y + shift * np.sin(pose.yaw),
        z=pose.z,
        yaw=pose.yaw,
    )
    update = {"depth": float(depth), "width": float(width), "height": float(height), "pose": moved}
    return scene.model_copy(update=update)


class TaskWorld:
    """A simulated task: the iiwa (7 joints, velocity-controlled) and a 1-DoF object.

    Shapes: robot configurations (7,) rad, object configurations (dof,) m or rad,
    poses (4, 4) in the world frame (robot base at the origin, z up).
    """

    n_robot = N_JOINTS

    def __init__(self, cfg: TaskConfig, model: ArticulatedObject) -> None:
        """Use `TaskWorld.create`. `model` is the true kinematic model (world frame)."""
        self.cfg = cfg
        self._model = model
        self.dof_object = model.dof
        self.dt = cfg.control_dt
        self.horizon = cfg.horizon
        self.goal = np.asarray(cfg.goal, dtype=np.float64)
        # PyBullet joint j is model.joints[j] (docs/objects.md); these are the movable ones
        self._object_joints = [j for j, joint in enumerate(model.joints) if joint.type != "fixed"]
        if self.goal.shape != (self.dof_object,):
            raise InputError(f"task.goal: expected {self.dof_object} values, got {cfg.goal}")
        if isinstance(cfg.scene, TBallScene):
            self.grasp_target_link = 1
            self.grasp_point: NDArray[np.float64] = np.zeros(3)
        else:
            self.grasp_target_link = model.link_index("handle_0")
            mesh = model.links[self.grasp_target_link].mesh
            self.grasp_point = handle_grasp_point(mesh, cfg.scene.parts.handle_thickness)
        self._sim_client: Any = connect_direct()
        self._query_client: Any = connect_direct()
        self._sim = self._build(self._sim_client)
        self._query = self._build(self._query_client)
        self._grasp: Grasp | None = None
        if cfg.grasp.enabled:
            # PyBullet link of model link i is i - 1 (docs/objects.md)
            target_link = -1 if self._sim.ball is not None else self.grasp_target_link - 1
            target_body = self._sim.ball if self._sim.ball is not None else self._sim.target
            self._grasp = Grasp(
                self._sim.robot, target_body, target_link, self.grasp_point, cfg.grasp
            )
        self._self_pairs = [(a, b) for a in range(-1, N_JOINTS) for b in range(a + 2, N_JOINTS)]
        self._ik_settings = IKSettings()
        self._initial_state = self._sim_client.saveState()
        self.reset(np.asarray(cfg.robot.start_q), np.asarray(cfg.object_start))

    @classmethod
    def create(cls, task_cfg: TaskConfig, rng: np.random.Generator | None = None) -> TaskWorld:
        """Build the world of `task_cfg`; `rng` draws the object geometry when the scene
        has `geometry_jitter > 0` (fixed geometry otherwise)."""
        scene = task_cfg.scene
        if isinstance(scene, TBallScene):
            return cls(task_cfg, tball_model(scene))
        sampled = sample_scene(scene, rng)
        return cls(task_cfg.model_copy(update={"scene": sampled}), build(sampled.spec()))

    def _build(self, client: Any) -> _Bodies:
        client.setGravity(0.0, 0.0, self.cfg.gravity)
        client.setTimeStep(self.cfg.physics_dt)
        scene = self.cfg.scene
        if isinstance(scene, TBallScene):
            ground = load_ground(client, scene.ball_rolling_friction)
            tball = load_tball(client, scene)
            target, ball = tball.tee, tball.ball
        else:
            ground = load_ground(client)
            target, ball = load_articulated(client, self._model), None
        return _Bodies(Robot.load(client, self.cfg.robot), ground, target, ball)

    # -- state -------------------------------------------------------------------------

    def _set_object(self, bodies: _Bodies, q_object: NDArray[np.float64]) -> None:
        q = np.asarray(q_object, dtype=np.float64).reshape(-1)
        if q.shape != (self.dof_object,):
            raise ValueError(f"q_object: expected ({self.dof_object},), got {q.shape}")
        client = bodies.robot.client
        if bodies.ball is not None:
            assert isinstance(self.cfg.scene, TBallScene)
            position = ball_start(self.cfg.scene) + np.array([0.0, q[0], 0.0])
            client.resetBasePositionAndOrientation(bodies.ball, position.tolist(), [0, 0, 0, 1])
            client.resetBaseVelocity(bodies.ball, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        else:
            for j, value in enumerate(q):
                client.resetJointState(bodies.target, self._object_joints[j], float(value), 0.0)

    def reset(self, q_robot: NDArray[np.float64], q_object: NDArray[np.float64]) -> None:
        """Kinematic reset: robot at q_robot (7,), object at q_object (dof,), all at rest,
        grasp released, robot motors holding still (see the module docstring)."""
        q = np.asarray(q_robot, dtype=np.float64).reshape(-1)
        if q.shape != (N_JOINTS,):
            raise ValueError(f"q_robot: expected ({N_JOINTS},), got {q.shape}")
        if self._grasp is not None:
            self._grasp.release()
        self._sim_client.restoreState(self._initial_state)
        self._sim.robot.set_state(q)
        self._set_object(self._sim, q_object)
        self._sim.robot.command_velocity(np.zeros(N_JOINTS))

    def robot_q(self) -> NDArray[np.float64]:
        """(7,) joint positions, rad."""
        return self._sim.robot.q()

    def robot_qd(self) -> NDArray[np.float64]:
        """(7,) joint velocities, rad/s."""
        return self._sim.robot.qd()

    def object_q(self) -> NDArray[np.float64]:
        """(dof,) object configuration q_O: joint value (m or rad), or for t-ball the
        ball's y displacement from its start, m."""
        client = self._sim_client
        if self._sim.ball is not None:
            assert isinstance(self.cfg.scene, TBallScene)
            position, _ = client.getBasePositionAndOrientation(self._sim.ball)
            return np.array([position[1] - ball_start(self.cfg.scene)[1]])
        states = client.getJointStates(self._sim.target, self._object_joints)
        return np.array([s[0] for s in states], dtype=np.float64)

    def ball_position(self) -> NDArray[np.float64] | None:
        """(3,) world position of the t-ball's ball, m (None for articulated scenes);
        read by `artic.sim.camera` to draw the ball where the simulation has it."""
        if self._sim.ball is None:
            return None
        position, _ = self._sim_client.getBasePositionAndOrientation(self._sim.ball)
        return np.asarray(position, dtype=np.float64)

    @property
    def grasp_held(self) -> bool:
        """Whether the grasp constraint currently holds the target."""
        return self._grasp is not None and self._grasp.held

    # -- control -----------------------------------------------------------------------

    def apply_action(self, qd_cmd: NDArray[np.float64]) -> NDArray[np.float64]:
        """Command joint velocities qd_cmd (7,) rad/s, clipped to the velocity limits;
        returns the clipped command. Takes effect at the next `step`."""
        command = np.asarray(qd_cmd, dtype=np.float64).reshape(-1)
        if command.shape != (N_JOINTS,) or not np.all(np.isfinite(command)):
            raise ValueError(f"qd_cmd: expected 7 finite joint velocities, got {qd_cmd!r}")
        return self._sim.robot.command_velocity(command)

    def step(self) -> None:
        """Advance one control period `dt` (`substeps` physics steps; the grasp model
        updates after each)."""
        for _ in range(self.cfg.substeps):
            self._sim_client.stepSimulation()
            if self._grasp is not None:
                self._grasp.update()

    # -- kinematic queries (query client) ----------------------------------------------

    def ee_pose(self, q_robot: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """(4, 4) world pose of the tool frame, at the simulated state or at q_robot (7,)."""
        if q_robot is None:
            return self._sim.robot.tool_pose()
        return self._query.robot.tool_pose_at(np.asarray(q_robot, dtype=np.float64))

    def ik(
        self, target: NDArray[np.float64], seed: NDArray[np.float64]
    ) -> NDArray[np.float64] | None:
        """Joint configuration (7,) putting the tool at `target` (4, 4), starting from
        `seed` (7,), or None if the residual check fails (`robot.solve_ik`)."""
        return solve_ik(
            self._query.robot, np.asarray(target, dtype=np.float64), seed, self._ik_settings
        )

    def in_collision(self, q_robot: NDArray[np.float64], q_object: NDArray[np.float64]) -> bool:
        """True if, at q_robot (7,) and q_object (dof,), the robot penetrates the object
        (or tee / ball) or the ground (links 1..6; the base stands on it), or two
        non-adjacent robot links penetrate each other."""
        bodies = self._query
        client = self._query_client
        bodies.robot.set_state(np.asarray(q_robot, dtype=np.float64))
        self._set_object(bodies, q_object)
        robot = bodies.robot.body
        others = [bodies.target] + ([bodies.ball] if bodies.ball is not None else [])
        for other in others:
            if client.getClosestPoints(robot, other, 0.0):
                return True
        if any(p[3] > 0 for p in client.getClosestPoints(robot, bodies.ground, 0.0)):
            return True
        return any(
            client.getClosestPoints(robot, robot, 0.0, linkIndexA=a, linkIndexB=b)
            for a, b in self._self_pairs
        )

    def robot_limits(self) -> RobotLimits:
        """Joint position limits (low (7,), high (7,)), rad, from the URDF."""
        return self._sim.robot.limits

    def velocity_limits(self) -> NDArray[np.float64]:
        """(7,) joint speed limits, rad/s."""
        return self._sim.robot.velocity_limits

    def kinematic_model(self) -> ArticulatedObject:
        """The TRUE kinematic model of the object, in the world frame (`base_pose`)."""
        return self._model

    # -- lifetime ----------------------------------------------------------------------

    def close(self) -> None:
        """Disconnect both clients (idempotent)."""
        for name in ("_sim_client", "_query_client"):
            client = getattr(self, name, None)
            if client is not None:
                client.disconnect()
                setattr(self, name, None)

    def __enter__(self) -> TaskWorld:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
