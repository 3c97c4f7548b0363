"""Gymnasium environments of Chapter 6 (section 6.4.1): `traj`, `door`, `push` under the
VICES or the RMP-VICES controller, in PyBullet with the iiwa in torque control.

`RmpEnv(task, controller, obstacles=False, seed=None)`:
- action a (12,) in [-1, 1]: the VICES action (`artic.control.osc.vices_command`), held
  for one 20 Hz period; the controller runs at every 240 Hz physics substep (torques
  clipped to the iiwa's, `artic.sim.robot.command_torque`);
- `controller="vices"`: Eq. 6.1 with the null-space posture term; `"rmp_vices"`: the
  RMP tree of section 6.3 (`artic.control.rmp`) with the table plane, the door panel
  (door task) and the evaluation spheres as obstacles of the collision dampers;
- a collision (a robot link, its base excepted, touching anything but the manipulated
  part: the door and its handle, or the block) or a joint within `joint_limit_margin`
  of a limit ends the episode (`terminated`) and costs `penalty` (section 6.4);
  `truncated` after `horizon` actions; collisions are checked after every substep and
  end the episode at the end of the action's period;
- `info`: `collision`, `joint_limit` (bools), `contact_force` (largest summed normal
  force of collision contacts over the period's substeps, N: Fig. 6.4), `success`;
- observations (float32, clipped to +-`OBS_BOUND`): end-effector position (3),
  quaternion (x, y, z, w) (4), linear and angular velocity (6), then per task: traj: via
  points (4 x 3) and checked flags (4); door: door angle and rate, handle position (3),
  grasp held (1); push: cube - hand (3), goal - cube (3), cube position (3);
- `obstacles=True`: `ObstacleConfig.count` spheres drawn at every reset (evaluation,
  section 6.5.2), clear of the task's protected points and of the arm's start pose; a
  task where they cannot be placed in `draws` draws is an InputError.
`reset(seed=...)` re-seeds the environment's generator (via points, block and goal,
start noise, spheres); the same seed gives the same episode, bit for bit.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Literal, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from artic.control.osc import (
    ArmState,
    VicesConfig,
    axis_angle_matrix,
    cross,
    vices_command,
    vices_torque,
)
from artic.control.rmp import (
    ControlPoints,
    Plane,
    RmpConfig,
    Sphere,
    rmp_torque,
    rmp_vices_acceleration,
)
from artic.errors import InputError
from artic.objects.categories import build
from artic.objects.spec import ObjectSpec, PartsConfig, Pose
from artic.sim.bullet import connect_direct
from artic.sim.rmp_tasks import Box3, DoorScene, PushScene, RmpTaskConfig, TrajScene, get_rmp_task
from artic.sim.robot import (
    N_JOINTS,
    TOOL_LINK,
    Grasp,
    IKSettings,
    Robot,
    cap_joint_speeds,
    command_torque,
    link_kinematics,
    pose_matrix,
    release_motors,
    solve_ik,
    tool_arm_state,
)
from artic.sim.scene import handle_grasp_point, load_articulated, load_ground
from artic.sim.tasks import GraspConfig

F64 = NDArray[np.float64]
Controller = Literal["vices", "rmp_vices"]
CONTROLLERS: tuple[Controller, ...] = ("vices", "rmp_vices")
OBS_BOUND = 10.0
PARKED = [0.0, 0.0, -10.0]  # where unused obstacle spheres wait, m


def push_reward(d_h2c: float, d_c2g: float, r_h2c: float, r_c2g: float) -> float:
    """Eq. 6.6: r_h2c (1 - tanh(20 d_h2c)) + r_c2g (1 - tanh(20 d_c2g)); distances m."""
    return r_h2c * (1.0 - np.tanh(20.0 * d_h2c)) + r_c2g * (1.0 - np.tanh(20.0 * d_c2g))


def _uniform(rng: np.random.Generator, box: Box3) -> F64:
    centre, half = np.asarray(box.centre), np.asarray(box.half_extents)
    return centre + rng.uniform(-1.0, 1.0, size=3) * half


class RmpEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """One Chapter 6 task under one controller (see the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium API)

    def __init__(
        self,
        task: str | RmpTaskConfig = "traj",
        controller: Controller = "rmp_vices",
        obstacles: bool = False,
        seed: int | None = None,
        vices: VicesConfig | None = None,
        rmp: RmpConfig | None = None,
    ) -> None:
        self.task = get_rmp_task(task) if isinstance(task, str) else task
        if controller not in CONTROLLERS:
            raise InputError(f"controller: unknown {controller!r}; known: vices, rmp_vices")
        self.controller: Controller = controller
        self.vices_cfg = vices or VicesConfig()
        self.rmp_cfg = rmp or RmpConfig()
        self.with_obstacles = obstacles
        self._rng = np.random.default_rng(seed)
        task_cfg = self.task
        self.client: Any = connect_direct()
        self._links = sorted({*task_cfg.control_points.links, TOOL_LINK})
        self._tool_row = self._links.index(TOOL_LINK)
        rows = [self._links.index(link) for link in task_cfg.control_points.links]
        self._point_rows = np.repeat(rows, 2)  # centre of mass, then frame origin
        self.start_q = np.asarray(task_cfg.robot.start_q, dtype=np.float64)
        self._door_model: Any = None
        if isinstance(task_cfg.scene, DoorScene):
            self._door_model = self._door_object(task_cfg.scene)
        self._build()
        low, high = self.robot.limits
        self.limits = (low, high)
        if self._door_model is not None:
            self.start_q = self._grasp_configuration()
        self.sphere_centres = np.zeros((0, 3))
        self._steps = 0
        self.via_points: F64 = np.zeros((0, 3))
        self.checked: NDArray[np.bool_] = np.zeros(0, dtype=bool)
        self.goal: F64 = np.zeros(3)
        n_obs = len(self._observation_parts())
        self.observation_space = gym.spaces.Box(-OBS_BOUND, OBS_BOUND, (n_obs,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (12,), np.float32)

    # -- building --------------------------------------------------------------------

    def _build(self) -> None:
        """Create the whole scene in the (empty) client. Every reset starts from
        `resetSimulation` and this same command sequence: PyBullet is then deterministic
        whatever happened before (a restored `saveState` kept the previous episode's
        broadphase pairs, which changed the block's first steps by ~1e-5 m)."""
        client, task_cfg = self.client, self.task
        client.setGravity(0.0, 0.0, task_cfg.gravity)
        client.setTimeStep(task_cfg.physics_dt)
        self.ground = load_ground(client)
        self.robot = Robot.load(client, task_cfg.robot)
        self._allowed: set[tuple[int, int]] = set()  # (body, link) the robot may touch
        self._grasp: Grasp | None = None
        self._door_body = self._block = -1
        scene = task_cfg.scene
        if isinstance(scene, DoorScene):
            self._build_door(scene)
        elif isinstance(scene, PushScene):
            self._build_push(scene)
        self._spheres = [self._sphere_body() for _ in range(task_cfg.obstacles.count)]

    def _door_object(self, scene: DoorScene) -> Any:
        parts = PartsConfig(joint_damping=scene.joint_damping, joint_friction=scene.joint_friction)
        spec = ObjectSpec(
            category="cabinet", index=0, dof=1, joint_type="revolute", depth=scene.depth,
            width=scene.width, height=scene.height, chirality=scene.chirality,
            pose=Pose(x=scene.x, y=scene.y, z=scene.z, yaw=0.0),
            joint_limits=((0.0, scene.door_limit),), parts=parts,
        )  # fmt: skip
        model = build(spec)
        hinge = model.joint_frames(np.zeros(1))[0]
        self._hinge_point = hinge[:3, 3].copy()
        self._hinge_axis = hinge[:3, :3] @ model.movable_joints[0].axis
        handle = model.link_index("handle_0")
        self._handle = handle
        self._grasp_local = handle_grasp_point(model.links[handle].mesh, parts.handle_thickness)
        return model

    def _build_door(self, scene: DoorScene) -> None:
        model = self._door_model
        self._door_body = load_articulated(self.client, model)
        # PyBullet link of model link i is i - 1 (docs/objects.md)
        self._allowed = {(self._door_body, 0), (self._door_body, 1)}
        self._grasp = Grasp(
            self.robot, self._door_body, self._handle - 1, self._grasp_local, GraspConfig()
        )

    def _grasp_target(self, angle: float) -> F64:
        """The tool pose (4, 4) holding the handle with the door at `angle`: at the
        handle's grasp point, its z axis into the door (+x when closed), turned with it."""
        target = np.eye(4)
        closed = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
        target[:3, :3] = axis_angle_matrix(self._hinge_axis * angle) @ closed
        pose = self._door_model.link_poses(np.array([angle]))[self._handle]
        target[:3, 3] = pose[:3, :3] @ self._grasp_local + pose[:3, 3]
        return target

    def _grasp_configuration(self) -> F64:
        """The start configuration of the door task: `_grasp_target(0)` by `solve_ik`
        from `robot.start_q`."""
        q = solve_ik(self.robot, self._grasp_target(0.0), self.start_q, IKSettings(rounds=20))
        if q is None:
            raise InputError("task.scene: the door handle is out of the iiwa's reach")
        return q

    def grasp_path(self, angles: F64) -> F64 | None:
        """Joint configurations (n, 7) that keep the handle grasped as at the start while
        the door turns through `angles` (rad, increasing from 0): `solve_ik` of each
        `_grasp_target`, warm-started from the previous one (the path a policy that opens
        the door without regrasping follows); None where IK fails. Door task only."""
        if self._door_model is None:
            raise ValueError("grasp_path: not the door task")
        q, path = self.start_q, []
        for angle in np.asarray(angles, dtype=np.float64):
            solved = solve_ik(
                self.robot, self._grasp_target(float(angle)), q, IKSettings(rounds=20)
            )
            if solved is None:
                return None
            q = solved
            path.append(q)
        return np.array(path)

    def _build_push(self, scene: PushScene) -> None:
        client = self.client
        half = scene.block_size / 2
        shape = client.createCollisionShape(client.GEOM_BOX, halfExtents=[half] * 3)
        self._block = int(
            client.createMultiBody(baseMass=scene.block_mass, baseCollisionShapeIndex=shape,
                                   basePosition=[0.6, 0.0, half])
        )  # fmt: skip
        client.changeDynamics(self._block, -1, lateralFriction=scene.block_friction)
        client.changeDynamics(self.ground, -1, lateralFriction=scene.block_friction)
        self._allowed = {(self._block, -1)}

    def _sphere_body(self) -> int:
        client = self.client
        shape = client.createCollisionShape(client.GEOM_SPHERE, radius=self.task.obstacles.radius)
        return int(client.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape,
                                          basePosition=PARKED))  # fmt: skip

    # -- state -----------------------------------------------------------------------

    def _joints(self) -> tuple[F64, F64]:
        states = self.client.getJointStates(self.robot.body, range(N_JOINTS))
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def arm_state(self, points: bool = True) -> tuple[ArmState, ControlPoints | None]:
        """The controllers' view of the arm (`ArmState`) and, if `points`, the control
        points of the collision RMPs with the curvature terms J'q' (VICES uses neither:
        then only the tool link is read), at the simulated state."""
        q, qd = self._joints()
        links = self._links if points else [TOOL_LINK]
        kin = link_kinematics(self.robot, links, q, qd, curvature=points)
        row = self._tool_row if points else 0
        state = tool_arm_state(self.robot, kin, row, q, qd, self.task.robot.tool_offset)
        if not points:
            return state, None
        rows = self._point_rows
        positions = np.empty((len(rows), 3))
        positions[0::2] = kin.com[rows[0::2]]
        positions[1::2] = kin.frame[rows[1::2]]
        offsets = positions - kin.com[rows]
        jw_rows = kin.jacobian[rows, 3:]  # (P, 3, 7)
        # r x (each column of J_w)
        turn = cross(offsets[:, None, :], jw_rows.transpose(0, 2, 1)).transpose(0, 2, 1)
        jac = kin.jacobian[rows, :3] - turn
        w_rows = kin.omega[rows]
        jdot = (kin.jdot_qdot[rows, :3] + cross(kin.jdot_qdot[rows, 3:], offsets)
                + cross(w_rows, cross(w_rows, offsets)))  # fmt: skip
        radii = np.full(len(rows), self.task.control_points.radius)
        return state, ControlPoints(positions, jac @ qd, jac, jdot, radii)

    def rmp_obstacles(self) -> list[Plane | Sphere]:
        """The obstacles the collision RMPs see now: the table plane, the door panel
        (through the hinge, turned with the door) and the placed spheres."""
        obstacles: list[Plane | Sphere] = [Plane(np.array([0.0, 0.0, 1.0]), 0.0)]
        if self._door_body >= 0:
            angle = float(self.client.getJointState(self._door_body, 0)[0])
            normal = axis_angle_matrix(self._hinge_axis * angle) @ np.array([-1.0, 0.0, 0.0])
            obstacles.append(Plane(normal, float(normal @ self._hinge_point)))
        obstacles.extend(Sphere(c, self.task.obstacles.radius) for c in self.sphere_centres)
        return obstacles

    def torque(self, action: F64) -> F64:
        """Unclipped joint torques (7,) of the controller for the VICES `action` (12,) at
        the simulated state (the set-point is re-derived from the current pose: use
        `step` for the held set-point of the thesis)."""
        state, points = self.arm_state(self.controller == "rmp_vices")
        command = vices_command(action, state.ee_position, state.ee_rotation, self.vices_cfg)
        return self._torque(command, state, points)

    def _torque(self, command: Any, state: ArmState, points: ControlPoints | None) -> F64:
        if self.controller == "vices":
            return vices_torque(state, command, self.start_q, self.vices_cfg)
        obstacles = self.rmp_obstacles()
        qdd = rmp_vices_acceleration(
            state, command, self.start_q, self.limits, points, obstacles, self.vices_cfg,
            self.rmp_cfg,
        )  # fmt: skip
        return rmp_torque(state, qdd)

    # -- episodes --------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        rng = self._rng
        client = self.client
        client.resetSimulation()
        self._build()
        noise = self.task.robot.start_noise
        q0 = self.start_q + (rng.normal(0.0, noise, N_JOINTS) if noise > 0 else 0.0)
        low, high = self.limits
        self.robot.set_state(np.clip(q0, low, high))
        release_motors(self.robot)
        cap_joint_speeds(self.robot)
        scene = self.task.scene
        protected: list[F64] = []
        if isinstance(scene, TrajScene):
            self.via_points = self._draw_via_points(scene, rng)
            self.checked = np.zeros(len(self.via_points), dtype=bool)
            protected = list(self.via_points)
        elif isinstance(scene, DoorScene):
            client.resetJointState(self._door_body, 0, 0.0, 0.0)
            assert self._grasp is not None
            self._grasp.update()
        else:
            assert isinstance(scene, PushScene)
            block = _uniform(rng, scene.block_start)
            block[2] = scene.block_size / 2
            self.goal = _uniform(rng, scene.goal)
            self.goal[2] = scene.block_size / 2
            client.resetBasePositionAndOrientation(self._block, block.tolist(), [0, 0, 0, 1])
            protected = [block, self.goal]
        centres = self._draw_spheres(rng, protected) if self.with_obstacles else np.zeros((0, 3))
        self.place_spheres(centres)
        self._steps = 0
        return self._observation(), self._info(False, False, 0.0)

    def place_spheres(self, centres: F64) -> None:
        """Put the obstacle spheres at `centres` (k, 3), k <= `obstacles.count`, the
        others parked far below; the RMPs see exactly these."""
        centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
        if len(centres) > len(self._spheres):
            raise ValueError(f"{len(centres)} spheres, the environment has {len(self._spheres)}")
        for i, body in enumerate(self._spheres):
            where = centres[i].tolist() if i < len(centres) else PARKED
            self.client.resetBasePositionAndOrientation(body, where, [0, 0, 0, 1])
        self.sphere_centres = centres

    def _draw_via_points(self, scene: TrajScene, rng: np.random.Generator) -> F64:
        points: list[F64] = []
        for _ in range(scene.n_points * 1000):
            p = _uniform(rng, scene.box)
            if all(np.linalg.norm(p - o) >= scene.min_separation for o in points):
                points.append(p)
                if len(points) == scene.n_points:
                    return np.array(points)
        raise InputError("task.scene.min_separation: via points cannot be placed that far apart")

    def _draw_spheres(self, rng: np.random.Generator, protected: list[F64]) -> F64:
        """Sphere centres (count, 3), clear of `protected` points, of each other, of the
        arm at its start pose, of the door's swing (door task); InputError after `draws`."""
        cfg = self.task.obstacles
        r, gap = cfg.radius, cfg.clearance
        _, points = self.arm_state()
        assert points is not None
        arm = points.positions
        keep_out = r + gap
        centres: list[F64] = []
        scene = self.task.scene
        for _ in range(cfg.draws):
            c = _uniform(rng, cfg.volume)
            if c[2] < r:
                continue
            if any(np.linalg.norm(c - p) < keep_out for p in protected):
                continue
            if any(np.linalg.norm(c - o) < 2 * r + gap for o in centres):
                continue
            if np.any(np.linalg.norm(arm - c, axis=1) < keep_out + points.radii):
                continue
            if isinstance(scene, DoorScene):
                swing = float(np.linalg.norm((c - self._hinge_point)[:2]))
                if swing < scene.width + keep_out:
                    continue
            centres.append(c)
            if len(centres) == cfg.count:
                return np.array(centres)
        raise InputError(
            f"task.obstacles: {cfg.count} spheres of radius {r} m cannot be placed clear in "
            f"{cfg.draws} draws"
        )

    def _collision_force(self) -> tuple[bool, float]:
        """(whether the robot touches anything it may not, their summed normal force N).
        PyBullet also lists contact points a few mm apart (within its contact threshold,
        with no force); only points at distance <= 0 (touching or penetrating) count."""
        hit, force = False, 0.0
        for contact in self.client.getContactPoints(bodyA=self.robot.body):
            body, link_a, link_b, distance = contact[2], contact[3], contact[4], contact[8]
            if link_a == -1 or (body, link_b) in self._allowed or distance > 0.0:
                continue
            hit, force = True, force + float(contact[9])
        return hit, force

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)
        with_points = self.controller == "rmp_vices"
        state, points = self.arm_state(with_points)
        command = vices_command(a, state.ee_position, state.ee_rotation, self.vices_cfg)
        collision, peak = False, 0.0
        for sub in range(self.task.substeps):
            if sub > 0:
                state, points = self.arm_state(with_points)
            command_torque(self.robot, self._torque(command, state, points))
            self.client.stepSimulation()
            if self._grasp is not None:
                self._grasp.update()
            hit, force = self._collision_force()
            peak = max(peak, force)
            collision = collision or hit
        # a collision ends the episode after the action's period, over which its largest
        # contact force is taken (at the first touching substep the solver has often not
        # pushed yet: its normal force reads 0)
        self._steps += 1
        q, _ = self._joints()
        low, high = self.limits
        margin = self.task.joint_limit_margin
        joint_limit = bool(np.any(q < low + margin) or np.any(q > high - margin))
        reward, success = self._reward()
        if collision or joint_limit:
            reward -= self.task.penalty
        truncated = self._steps >= self.task.horizon
        info = self._info(collision, joint_limit, peak)
        info["success"] = success
        return self._observation(), reward, collision or joint_limit, truncated, info

    def _tool(self) -> tuple[F64, F64]:
        state = self.client.getLinkState(self.robot.body, TOOL_LINK, computeForwardKinematics=1)
        pose = pose_matrix(state[4], state[5])
        return pose[:3, 3] + pose[:3, 2] * self.task.robot.tool_offset, pose[:3, :3]

    def _reward(self) -> tuple[float, bool]:
        scene = self.task.scene
        tool, _ = self._tool()
        if isinstance(scene, TrajScene):
            reward = 0.0
            nxt = int(np.argmin(self.checked)) if not self.checked.all() else -1
            if nxt >= 0 and np.linalg.norm(tool - self.via_points[nxt]) < scene.reach_distance:
                self.checked[nxt] = True
                reward += scene.bonus
                nxt = int(np.argmin(self.checked)) if not self.checked.all() else -1
            d = float(np.linalg.norm(tool - self.via_points[nxt]))
            if nxt < 0:
                d = 0.0
            return reward + scene.shaping * (1.0 - np.tanh(10.0 * d)), bool(self.checked.all())
        if isinstance(scene, DoorScene):
            angle = self.door_angle()
            fraction = float(np.clip(angle / scene.goal_angle, 0.0, 1.0))
            return scene.reward_scale * fraction, angle >= scene.goal_angle
        assert isinstance(scene, PushScene)
        block = self.block_position()
        d_h2c = float(np.linalg.norm(tool - block))
        d_c2g = float(np.linalg.norm((block - self.goal)[:2]))
        reward = push_reward(d_h2c, d_c2g, scene.r_h2c, scene.r_c2g)
        return reward, d_c2g <= scene.success_distance

    def door_angle(self) -> float:
        """The door's opening angle, rad (door task)."""
        return float(self.client.getJointState(self._door_body, 0)[0])

    def block_position(self) -> F64:
        """(3,) the cube's centre, m (push task)."""
        return np.asarray(self.client.getBasePositionAndOrientation(self._block)[0])

    @property
    def grasp_held(self) -> bool:
        return self._grasp is not None and self._grasp.held

    def _info(self, collision: bool, joint_limit: bool, force: float) -> dict[str, Any]:
        return {"collision": collision, "joint_limit": joint_limit, "contact_force": force,
                "success": False}  # fmt: skip

    def _observation_parts(self) -> F64:
        tool, _ = self._tool()
        q, qd = self._joints()
        kin = link_kinematics(self.robot, [TOOL_LINK], q, qd, curvature=False)
        r = tool - kin.com[0]
        twist = np.concatenate([kin.velocity[0] + cross(kin.omega[0], r), kin.omega[0]])
        quaternion = np.array(self.client.getLinkState(self.robot.body, TOOL_LINK)[5])
        parts = [tool, -quaternion if quaternion[3] < 0 else quaternion, twist]
        scene = self.task.scene
        if isinstance(scene, TrajScene):
            n = scene.n_points
            via = self.via_points if len(self.via_points) else np.zeros((n, 3))
            flags = self.checked if len(self.checked) else np.zeros(n, dtype=bool)
            parts += [via.reshape(-1), flags.astype(np.float64)]
        elif isinstance(scene, DoorScene):
            angle, rate = self.client.getJointState(self._door_body, 0)[:2]
            assert self._grasp is not None
            handle = self._grasp.target_point()
            parts += [np.array([angle, rate]), handle, np.array([float(self.grasp_held)])]
        else:
            block = self.block_position()
            parts += [block - tool, (self.goal - block), block]
        return np.concatenate(parts)

    def _observation(self) -> NDArray[np.float32]:
        return np.clip(self._observation_parts(), -OBS_BOUND, OBS_BOUND).astype(np.float32)

    def close(self) -> None:
        if getattr(self, "client", None) is not None:
            self.client.disconnect()
            self.client = None
        super().close()


def measure_steps_per_second(
    task: str,
    controller: Controller,
    n: int = 200,
    seed: int = 0,
    clock: Callable[[], float] = time.perf_counter,
) -> float:
    """Control steps (20 Hz actions, 12 physics substeps each with the controller) per
    second of `clock` (wall clock; `time.process_time` for the CPU time of this process,
    a per-core rate on a busy machine) under random actions, resets included. A
    benchmark helper, not used by tests."""
    env = RmpEnv(task, controller, seed=seed)
    try:
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        start = clock()
        for _ in range(n):
            action = rng.uniform(-1.0, 1.0, size=12).astype(np.float32)
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        return n / (clock() - start)
    finally:
        env.close()
