"""Gymnasium environments of Chapter 7 (section 7.3): the contact phase pi_c of a CIP on
`door`, `drawer`, `slide`, `lever`, in PyBullet with the iiwa in torque control and the
parallel-jaw gripper (`sim/gripper.py`).

`CipEnv(task, safety=True, contact_termination=True, seed=None)`:
- action a (13,) in [-1, 1] (section 7.2.1): a[:12] the VICES action (`control/osc.py`:
  displacement, rotation, stiffnesses), its displacement and rotation given in the
  object's frame (so a skill moves with the object), held for one 20 Hz period; a[12]
  Gamma: > 0 closes the gripper, else opens it. The controller runs at every 240 Hz
  substep with the gripper's mass in its model; with `safety`, the envelope sigma
  (`control/safety.py`: stiffness cap, null-space and push modes), else the torques are
  only clipped to the iiwa's;
- observation (30,) float32, in the object's frame: q_O, q_O' (2), q (7), q' (7), the
  tool point (3) and orientation quaternion x, y, z, w (4), the finger opening (1), the
  tactile zones (6, N; `Gripper.tactile`);
- reward: 1 when beta_c holds (q_O >= `success`) plus the potential shaping
  gamma Phi(s') - Phi(s), Phi = q_O / success (`sim/shaping.py`);
- `terminated` when beta_c holds or B does: a joint within `safety.limit_threshold` of a
  limit, or, with `contact_termination` (every setting but E2E), no finger contact for
  `contact_loss_steps` actions; `truncated` after `horizon` actions;
- `info`: `success`, `joint_limit`, `contact_lost`, `envelope` (substeps per mode).
`reset(seed=..., options=...)`: the object's pose is drawn (+-`jitter_xy`, +-`jitter_yaw`)
from the environment's generator, the scene rebuilt (bit-for-bit deterministic, as
Chapter 6's), then the robot placed: `options["start_q"]` (7,) (the head's end, from a
grasp: `artic.planning`), else home (`robot.start_q`, E2E); or `options["track"]`, a
timed joint reference {"q": (T, 7), "qd": (T, 7), "k_p": 1/s^2} sampled at the physics
step (a planned head, `head.execute=track`): the arm placed at its first sample and
driven along it by computed torque with the hand open (`follow`); `options["grasp"]`
true then closes the gripper for `grasp_time` while VICES holds the pose (Gamma,
Algorithm 3 line 10). `object_pose` (4, 4) is the episode's object frame; `draw_pose(seed)` gives
the pose a reset with that seed will use, so a head can solve IK for it first.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from artic.control.osc import ArmState, VicesCommand, vices_command, vices_torque
from artic.control.safety import cap_stiffness, envelope_torque, limit_distance
from artic.control.tracking import computed_torque
from artic.objects.categories import build
from artic.objects.model import ArticulatedObject
from artic.objects.spec import ObjectSpec, PartsConfig, Pose
from artic.sim.bullet import connect_direct
from artic.sim.cip_tasks import CipTaskConfig, get_cip_task
from artic.sim.gripper import Gripper
from artic.sim.robot import (
    IIWA7_TORQUE_LIMITS,
    N_JOINTS,
    TOOL_LINK,
    Robot,
    cap_joint_speeds,
    command_torque,
    link_kinematics,
    release_motors,
    tool_arm_state,
)
from artic.sim.scene import handle_grasp_point, load_articulated, load_ground
from artic.sim.shaping import potential

F64 = NDArray[np.float64]
OBS_SIZE = 30
OBS_BOUND = 10.0
ENVELOPE_MODES = ("pass", "null_space", "push")


def yaw_pose(x: float, y: float, z: float, yaw: float) -> F64:
    """(4, 4) pose: translation (x, y, z), rotation yaw about z."""
    pose = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    pose[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = x, y, z
    return pose


def draw_object_pose(task: CipTaskConfig, rng: np.random.Generator) -> F64:
    """(4, 4) a pose of `task`'s object: its nominal one jittered (+-`jitter_xy` in x and
    y, +-`jitter_yaw` about z), drawn from `rng`."""
    o = task.object
    dx, dy = rng.uniform(-o.jitter_xy, o.jitter_xy, size=2)
    dyaw = rng.uniform(-o.jitter_yaw, o.jitter_yaw)
    return yaw_pose(o.x + dx, o.y + dy, o.z, float(dyaw))


def task_spec(task: CipTaskConfig, pose: F64) -> ObjectSpec:
    """The `artic.objects` spec of `task`'s object with its base at `pose` (4, 4; z up)."""
    o = task.object
    yaw = float(np.arctan2(pose[1, 0], pose[0, 0]))
    return ObjectSpec(
        category=o.category, index=0, dof=1, joint_type=o.joint_type, depth=o.depth,
        width=o.width, height=o.height, chirality=o.chirality,
        pose=Pose(x=float(pose[0, 3]), y=float(pose[1, 3]), z=float(pose[2, 3]), yaw=yaw),
        joint_limits=((0.0, o.joint_limit),), parts=o.parts,
    )  # fmt: skip


def task_object(task: CipTaskConfig, pose: F64) -> ArticulatedObject:
    """`task`'s object (`artic.objects`, closed) with its base at `pose` (4, 4; z up)."""
    return build(task_spec(task, pose))


class CipEnv(gym.Env[NDArray[np.float32], NDArray[np.float32]]):
    """The contact phase of one Chapter 7 task (see the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium API)

    def __init__(
        self,
        task: str | CipTaskConfig = "door",
        safety: bool = True,
        contact_termination: bool = True,
        seed: int | None = None,
    ) -> None:
        self.task = get_cip_task(task) if isinstance(task, str) else task
        self.safety = safety
        self.contact_termination = contact_termination
        self._safety_cfg = self.task.safety.model_copy(update={"enabled": safety})
        self._rng = np.random.default_rng(seed)
        self._robot_cfg = self.task.robot.model_copy(
            update={"tool_offset": self.task.gripper.tool_offset}
        )
        self.client: Any = connect_direct()
        self.object_pose = self._draw(self._rng)
        self._build()
        self.limits = self.robot.limits
        self.rest_q = np.asarray(self._robot_cfg.start_q, dtype=np.float64)
        self._steps = self._no_contact = 0
        self._phi = 0.0
        #: subtracted from q in the observation: compose turns a skill's scene about the
        #: base's vertical axis (joint 1's), and joint 1 is then read from the object's
        #: bearing (zero here: the training scene)
        self.joint_offset = np.zeros(N_JOINTS)
        self.observation_space = gym.spaces.Box(-OBS_BOUND, OBS_BOUND, (OBS_SIZE,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (13,), np.float32)

    # -- the scene ---------------------------------------------------------------------

    def _draw(self, rng: np.random.Generator) -> F64:
        return draw_object_pose(self.task, rng)

    def draw_pose(self, seed: int) -> F64:
        """(4, 4) the object pose `reset(seed=seed)` will use."""
        return self._draw(np.random.default_rng(seed))

    def object_model(self, pose: F64 | None = None) -> ArticulatedObject:
        """The task's object (`artic.objects`) at `pose` (default: this episode's)."""
        return task_object(self.task, self.object_pose if pose is None else pose)

    @property
    def parts(self) -> PartsConfig:
        """The object's part constants (`CipObject.parts`)."""
        return self.task.object.parts

    def _build(self) -> None:
        """The whole scene in the (empty) client, always by the same command sequence."""
        self._load_arm()
        self.model = self.object_model()
        self.object = load_articulated(self.client, self.model)

    def _load_arm(self) -> None:
        """Physics settings, the table, the iiwa (its joint speeds capped:
        `cap_joint_speeds`) and the gripper."""
        client, task = self.client, self.task
        client.setGravity(0.0, 0.0, task.gravity)
        client.setTimeStep(task.physics_dt)
        self.ground = load_ground(client)
        self.robot = Robot.load(client, self._robot_cfg)
        cap_joint_speeds(self.robot)
        self.gripper = Gripper(client, self.robot, task.gripper, task.gravity)

    # -- state ---------------------------------------------------------------------------

    def _joints(self) -> tuple[F64, F64]:
        states = self.client.getJointStates(self.robot.body, range(N_JOINTS))
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def object_joint(self) -> tuple[float, float]:
        """(q_O, q_O') of the object's joint, rad or m (and per s)."""
        state = self.client.getJointState(self.object, 0)
        return float(state[0]), float(state[1])

    def arm_state(self) -> ArmState:
        """The controller's view of the arm with the gripper's mass in M and C q' + g."""
        q, qd = self._joints()
        kin = link_kinematics(self.robot, [TOOL_LINK], q, qd, curvature=False)
        state = tool_arm_state(self.robot, kin, 0, q, qd, self.task.gripper.tool_offset)
        payload = self.gripper.payload(q)
        return state._replace(mass=state.mass + payload.mass, bias=state.bias + payload.bias)

    def touching(self) -> F64:
        """(6,) the tactile zones, N: contacts of the fingers with anything but the arm."""
        return self.gripper.tactile(exclude=(self.robot.body, self.gripper.body))

    def handle_grasp(self, pose: F64 | None = None) -> F64:
        """(4, 4) world tool pose holding the handle (`handle_0`) at the middle of its
        bar, the object closed at `pose` (default: this episode's): z (the approach) into
        the object's front (+x of its frame), the fingers closing across the bar (y
        perpendicular to it), the fingertips clear of the surface behind the handle. The
        reference grasp of the task (demonstrations, tests)."""
        pose = self.object_pose if pose is None else pose
        model = self.object_model(pose)
        link = model.link_index("handle_0")
        frame = model.link_poses(np.zeros(1))[link]
        mesh = model.links[link].mesh
        extent = mesh.vertices.max(axis=0) - mesh.vertices.min(axis=0)
        bar = frame[:3, :3] @ (np.eye(3)[1] if extent[1] > extent[2] else np.eye(3)[2])
        approach = pose[:3, :3] @ np.eye(3)[0]
        across = np.cross(approach, bar)
        grasp = np.eye(4)
        grasp[:3, 1] = across / np.linalg.norm(across)
        grasp[:3, 2] = approach
        grasp[:3, 0] = np.cross(grasp[:3, 1], approach)
        # the pads' centre `thickness / 2` behind the handle's front, or further out so
        # the fingertips stay `grasp_clearance` off the surface it stands on (a knob)
        point = handle_grasp_point(mesh, self.parts.handle_thickness)
        depth = float(extent[0])
        reach = depth - self.task.grasp_clearance - self.task.gripper.finger_length / 2
        point[0] = mesh.vertices[:, 0].min() + min(self.parts.handle_thickness / 2, reach)
        grasp[:3, 3] = frame[:3, :3] @ point + frame[:3, 3]
        return grasp

    # -- episodes ------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        options = options or {}
        self.object_pose = self._draw(self._rng)
        self.client.resetSimulation()
        self._build()
        track = options.get("track")
        start = options.get("start_q") if track is None else track["q"][0]
        q0 = self.rest_q if start is None else np.asarray(start, dtype=np.float64)
        if q0.shape != (N_JOINTS,) or not np.all(np.isfinite(q0)):
            raise ValueError(f"start_q: {N_JOINTS} finite joint angles expected")
        self.robot.set_state(q0)
        self.gripper.follow()
        self.gripper.set_opening(self.task.gripper.travel)
        release_motors(self.robot)
        self.rest_q = q0
        info = self._info(False, False, False, {})
        if track is not None:
            info["head_error"] = self.follow(track["q"], track["qd"], float(track["k_p"]))
            self.rest_q = self._joints()[0]
        if options.get("grasp", False):
            self._close_on_grasp()
        self._steps = self._no_contact = 0
        self._phi = self._potential()
        return self._observation(), info

    def follow(self, q_ref: F64, qd_ref: F64, k_p: float) -> float:
        """Drive the arm along the joint reference q_ref, qd_ref (T, 7), one sample per
        physics step, by computed torque (gains k_p, 2 sqrt(k_p); `control/tracking.py`)
        with the gripper's mass in the model; returns the largest joint error at the
        end, rad (a head's tracking error)."""
        k_d = 2.0 * float(np.sqrt(k_p))
        for q, qd in zip(np.asarray(q_ref), np.asarray(qd_ref), strict=True):
            state = self.arm_state()
            tau = computed_torque(state.mass, state.bias, state.q, state.qd, q, qd, k_p, k_d)
            command_torque(self.robot, tau)
            self.client.stepSimulation()
        return float(np.abs(self._joints()[0] - np.asarray(q_ref)[-1]).max())

    def grasp_here(self) -> NDArray[np.float32]:
        """Gamma where the arm stands (a tracked head's end): the posture target set
        there, the fingers closed as at a reset with `grasp`; the episode's counters
        restarted. Returns the observation."""
        self.rest_q = self._joints()[0]
        self._close_on_grasp()
        self._steps = self._no_contact = 0
        self._phi = self._potential()
        return self._observation()

    def _close_on_grasp(self) -> None:
        """Gamma at the head's end: close the fingers while VICES holds the tool still."""
        state = self.arm_state()
        command = vices_command(np.zeros(12), state.ee_position, state.ee_rotation,
                                self.task.vices)  # fmt: skip
        self.gripper.command(close=True)
        for _ in range(round(self.task.grasp_time / self.task.physics_dt)):
            self._substep(command)

    def _substep(self, command: VicesCommand) -> str:
        state = self.arm_state()
        torque = vices_torque(state, command, self.rest_q, self.task.vices)
        low, high = self.limits
        safe = envelope_torque(state, torque, low, high, np.asarray(IIWA7_TORQUE_LIMITS),
                               self._safety_cfg)  # fmt: skip
        command_torque(self.robot, safe.torque)
        self.client.stepSimulation()
        return safe.mode

    def to_world(self, action: F64) -> F64:
        """The VICES action (12,) with its displacement and rotation turned from the
        object's frame into the world's (stiffnesses unchanged)."""
        rotation = self.object_pose[:3, :3]
        out = np.array(action[:12], dtype=np.float64)
        out[:3], out[3:6] = rotation @ out[:3], rotation @ out[3:6]
        return out

    def step(
        self, action: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)
        if a.shape != (13,):
            raise ValueError(f"action: 13 values expected, got {a.shape}")
        state = self.arm_state()
        command = vices_command(self.to_world(a), state.ee_position, state.ee_rotation,
                                self.task.vices)  # fmt: skip
        if self.safety:
            command = cap_stiffness(command, self.task.safety.kp_max)
        self.gripper.command(close=bool(a[12] > 0))
        modes = dict.fromkeys(ENVELOPE_MODES, 0)
        for _ in range(self.task.substeps):
            modes[self._substep(command)] += 1
        self._steps += 1
        q, _ = self._joints()
        low, high = self.limits
        joint_limit = bool(limit_distance(q, low, high).distance.min()
                           < self.task.safety.limit_threshold)  # fmt: skip
        self._no_contact = 0 if self.touching().sum() > 0 else self._no_contact + 1
        contact_lost = self.contact_termination and self._no_contact >= self.task.contact_loss_steps
        q_o, _ = self.object_joint()
        success = q_o >= self.task.success
        phi = self._potential()
        reward = float(success) + self.task.gamma * phi - self._phi
        self._phi = phi
        terminated = bool(success or joint_limit or contact_lost)
        truncated = self._steps >= self.task.horizon
        info = self._info(bool(success), joint_limit, contact_lost, modes)
        return self._observation(), reward, terminated, truncated, info

    def _potential(self) -> float:
        q_o, _ = self.object_joint()
        return float(potential(np.array([q_o]), self.task.success)[0])

    def _info(
        self, success: bool, joint_limit: bool, contact_lost: bool, modes: dict[str, int]
    ) -> dict[str, Any]:
        return {"success": success, "joint_limit": joint_limit, "contact_lost": contact_lost,
                "envelope": modes}  # fmt: skip

    def tool_in_object(self) -> tuple[F64, F64]:
        """The tool point (3,) and the tool's rotation (3, 3) in the object's frame."""
        state = self.client.getLinkState(self.robot.body, TOOL_LINK, computeForwardKinematics=1)
        rotation = np.reshape(self.client.getMatrixFromQuaternion(state[5]), (3, 3))
        tool = np.asarray(state[4]) + rotation[:, 2] * self.task.gripper.tool_offset
        inverse = self.object_pose[:3, :3].T
        return inverse @ (tool - self.object_pose[:3, 3]), inverse @ rotation

    def observe(self) -> NDArray[np.float32]:
        """The observation (30,) of the current state (as `step` returns it)."""
        return self._observation()

    def _observation(self) -> NDArray[np.float32]:
        q, qd = self._joints()
        tool, rotation = self.tool_in_object()
        quaternion = Rotation.from_matrix(rotation).as_quat()
        if quaternion[3] < 0:
            quaternion = -quaternion
        parts = [np.array(self.object_joint()), q - self.joint_offset, qd, tool, quaternion,
                 np.array([self.gripper.width()]), self.touching()]  # fmt: skip
        obs = np.concatenate(parts)
        return np.clip(obs, -OBS_BOUND, OBS_BOUND).astype(np.float32)

    def close(self) -> None:
        if getattr(self, "client", None) is not None:
            self.client.disconnect()
            self.client = None
        super().close()
