"""The 7-DoF KUKA LBR iiwa in a PyBullet client: loading, joint state, velocity control,
forward and inverse kinematics of the tool frame, and the grasp model.

The robot is `pybullet_data`'s `kuka_iiwa/model.urdf` with a fixed base at the world
origin. Its tool frame is the last link's URDF frame translated by `tool_offset` along
that link's z axis (out of the flange): the fingertip point of a virtual gripper.
Every function takes the client explicitly; nothing here holds a module-level client.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from artic.control.osc import ArmState, cross, skew
from artic.sim.tasks import GraspConfig, RobotConfig

N_JOINTS = 7
TOOL_LINK = 6  # PyBullet link index of lbr_iiwa_link_7


def pose_matrix(position: Any, quaternion: Any) -> NDArray[np.float64]:
    """(4, 4) pose from a position (3,) and a unit PyBullet quaternion (x, y, z, w).

    Written out (not scipy's Rotation) because the grasp model calls it every substep."""
    x, y, z, w = (float(v) for v in quaternion)
    pose = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), 0.0],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), 0.0],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    pose[:3, 3] = position
    return pose


def rotate(quaternion: Any, vector: Any) -> tuple[float, float, float]:
    """Rotate vector (3,) by a unit quaternion (x, y, z, w): v + 2w (u x v) + 2 u x (u x v).

    Plain floats (no numpy): the grasp model calls it every physics substep."""
    x, y, z, w = (float(c) for c in quaternion)
    vx, vy, vz = (float(c) for c in vector)
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


def pose_to_pybullet(pose: NDArray[np.float64]) -> tuple[list[float], list[float]]:
    """(position (3,), quaternion (x, y, z, w)) of a (4, 4) pose."""
    quaternion = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return pose[:3, 3].tolist(), quaternion.tolist()


def rotation_error(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Angle (rad) of the relative rotation between two (3, 3) rotation matrices."""
    cosine = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.arccos(np.clip(cosine, -1.0, 1.0)))


class RobotLimits(NamedTuple):
    """Joint position limits of the robot: low (7,), high (7,), rad."""

    low: NDArray[np.float64]
    high: NDArray[np.float64]


@dataclass
class Robot:
    """The iiwa loaded in one client. `body` is its PyBullet id, joints 0..6 its DoF."""

    client: Any
    body: int
    cfg: RobotConfig
    limits: RobotLimits
    max_force: NDArray[np.float64]

    @classmethod
    def load(cls, client: Any, cfg: RobotConfig) -> Robot:
        """Load the URDF from `pybullet_data` with a fixed base at the origin."""
        import pybullet_data

        body = client.loadURDF(
            f"{pybullet_data.getDataPath()}/{cfg.urdf}",
            basePosition=[0.0, 0.0, 0.0],
            useFixedBase=True,
        )
        if client.getNumJoints(body) != N_JOINTS:
            raise ValueError(f"robot.urdf: expected {N_JOINTS} joints in {cfg.urdf}")
        info = [client.getJointInfo(body, j) for j in range(N_JOINTS)]
        low = np.array([i[8] for i in info], dtype=np.float64)
        high = np.array([i[9] for i in info], dtype=np.float64)
        force = np.array([i[10] for i in info], dtype=np.float64)
        robot = cls(client, body, cfg, RobotLimits(low, high), force)
        robot.set_state(np.asarray(cfg.start_q, dtype=np.float64))
        return robot

    @property
    def velocity_limits(self) -> NDArray[np.float64]:
        """(7,) joint speed limits, rad/s (`RobotConfig.velocity_limits`)."""
        return np.asarray(self.cfg.velocity_limits, dtype=np.float64)

    def set_state(self, q: NDArray[np.float64], qd: NDArray[np.float64] | None = None) -> None:
        """Kinematic reset of the joints to q (7,) rad and qd (7,) rad/s (default 0)."""
        velocities = np.zeros(N_JOINTS) if qd is None else qd
        for j in range(N_JOINTS):
            self.client.resetJointState(self.body, j, float(q[j]), float(velocities[j]))

    def q(self) -> NDArray[np.float64]:
        """(7,) joint positions, rad."""
        states = self.client.getJointStates(self.body, range(N_JOINTS))
        return np.array([s[0] for s in states], dtype=np.float64)

    def qd(self) -> NDArray[np.float64]:
        """(7,) joint velocities, rad/s."""
        states = self.client.getJointStates(self.body, range(N_JOINTS))
        return np.array([s[1] for s in states], dtype=np.float64)

    def command_velocity(self, qd_cmd: NDArray[np.float64]) -> NDArray[np.float64]:
        """Joint velocity motors (VELOCITY_CONTROL) at qd_cmd (7,) rad/s clipped to the
        velocity limits, with the URDF's effort limits as the largest motor forces.
        Returns the clipped command (7,)."""
        limit = self.velocity_limits
        command = np.clip(np.asarray(qd_cmd, dtype=np.float64), -limit, limit)
        self.client.setJointMotorControlArray(
            self.body,
            list(range(N_JOINTS)),
            self.client.VELOCITY_CONTROL,
            targetVelocities=command.tolist(),
            forces=self.max_force.tolist(),
        )
        return command

    def link_frame(self, link: int = TOOL_LINK) -> NDArray[np.float64]:
        """(4, 4) world pose of a link's URDF frame at the current joint state."""
        state = self.client.getLinkState(self.body, link, computeForwardKinematics=True)
        return pose_matrix(state[4], state[5])

    def tool_from_link(self) -> NDArray[np.float64]:
        """(4, 4) tool frame in the last link's URDF frame: a translation along z."""
        offset = np.eye(4)
        offset[2, 3] = self.cfg.tool_offset
        return offset

    def tool_pose(self) -> NDArray[np.float64]:
        """(4, 4) world pose of the tool frame at the current joint state."""
        return self.link_frame() @ self.tool_from_link()

    def tool_pose_at(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Forward kinematics: the tool pose (4, 4) at q (7,); leaves the joints at q."""
        self.set_state(q)
        return self.tool_pose()


class IKSettings(NamedTuple):
    """Inverse kinematics tolerances: position (m) and rotation (rad) residuals accepted,
    refinement rounds, and PyBullet's iterations per round."""

    position_tolerance: float = 0.005
    rotation_tolerance: float = 0.05
    rounds: int = 8
    iterations: int = 100


def solve_ik(
    robot: Robot,
    target: NDArray[np.float64],
    seed: NDArray[np.float64],
    settings: IKSettings = IKSettings(),
) -> NDArray[np.float64] | None:
    """Joint configuration (7,) whose tool pose is `target` (4, 4), or None.

    PyBullet's damped-least-squares `calculateInverseKinematics` (null space towards
    `seed`, within the joint limits) on the link frame that puts the tool at `target`,
    repeated from its own answer for up to `settings.rounds` rounds; the answer is
    clipped to the joint limits and accepted only if forward kinematics puts the tool
    within the position and rotation tolerances (the residual check). `robot` must live
    in a query client: its joints are moved.
    """
    link_target = target @ np.linalg.inv(robot.tool_from_link())
    position, quaternion = pose_to_pybullet(link_target)
    low, high = robot.limits
    q = np.clip(np.asarray(seed, dtype=np.float64), low, high)
    for _ in range(settings.rounds):
        robot.set_state(q)
        solution = robot.client.calculateInverseKinematics(
            robot.body,
            TOOL_LINK,
            position,
            quaternion,
            lowerLimits=low.tolist(),
            upperLimits=high.tolist(),
            jointRanges=(high - low).tolist(),
            restPoses=q.tolist(),
            maxNumIterations=settings.iterations,
            residualThreshold=1e-6,
        )
        q = np.clip(np.asarray(solution[:N_JOINTS], dtype=np.float64), low, high)
        reached = robot.tool_pose_at(q)
        position_error = float(np.linalg.norm(reached[:3, 3] - target[:3, 3]))
        angle_error = rotation_error(reached[:3, :3], target[:3, :3])
        if (
            position_error <= settings.position_tolerance
            and angle_error <= settings.rotation_tolerance
        ):
            return q
    return None


class Grasp:
    """The grasp model of the drawer task (a virtual gripper that closes by itself).

    Each physics substep `update()` does one of:
    - attach: if no grasp is held and the tool point is within `attach_distance` of the
      grasp point (a fixed point of the target link, e.g. the centre of a handle bar),
      a JOINT_POINT2POINT constraint ties the tool point to the grasp point, with
      `max_force` as the largest force the constraint may apply (the fingers close on
      the bar and centre it: the remaining gap closes under that force, no rotation is
      constrained);
    - slip: if a grasp is held and the two constrained points have drifted more than
      `slip_distance` apart (the constraint saturated at `max_force`: the robot pulled
      harder or faster than the handle could follow), the constraint is removed.
    A released grasp re-attaches only when the tool returns within `attach_distance`.
    """

    def __init__(
        self,
        robot: Robot,
        body: int,
        link: int,
        grasp_point: NDArray[np.float64],
        cfg: GraspConfig,
    ) -> None:
        """body/link: PyBullet ids of the target; grasp_point: (3,) in its URDF link
        frame, m."""
        self.robot, self.body, self.link, self.cfg = robot, body, link, cfg
        self.grasp_point = np.asarray(grasp_point, dtype=np.float64)
        self.constraint: int | None = None
        self._tool_local: NDArray[np.float64] = np.zeros(
            3
        )  # tool point in the robot link's inertial frame
        self._target_local: NDArray[np.float64] = np.zeros(
            3
        )  # held point in the target link's inertial frame

    @property
    def held(self) -> bool:
        return self.constraint is not None

    def _point(self, body: int, link: int, local: Any, inertial: bool) -> NDArray[np.float64]:
        """World position (3,) of `local` (3,) given in a link's URDF frame, or in its
        centre-of-mass frame if `inertial`; link -1 is the base (URDF frame = inertial
        frame for the bodies built here). Reads the link state the last physics step
        left (no forward-kinematics recompute: this runs every substep)."""
        client = self.robot.client
        if link == -1:
            position, quaternion = client.getBasePositionAndOrientation(body)
        else:
            state = client.getLinkState(body, link)
            position, quaternion = (state[0], state[1]) if inertial else (state[4], state[5])
        offset = rotate(quaternion, local)
        return np.array([position[0] + offset[0], position[1] + offset[1], position[2] + offset[2]])

    def _local(self, body: int, link: int, point: NDArray[np.float64]) -> NDArray[np.float64]:
        """`point` (3,) world, in the link's centre-of-mass frame (constraint pivots)."""
        client = self.robot.client
        if link == -1:
            position, quaternion = client.getBasePositionAndOrientation(body)
        else:
            position, quaternion = client.getLinkState(body, link)[:2]
        x, y, z, w = quaternion
        return np.array(rotate((-x, -y, -z, w), np.subtract(point, position)))

    def target_point(self) -> NDArray[np.float64]:
        """(3,) world position of the grasp point, m."""
        return self._point(self.body, self.link, self.grasp_point, inertial=False)

    def tool_point(self) -> NDArray[np.float64]:
        """(3,) world position of the tool point, m."""
        offset = (0.0, 0.0, self.robot.cfg.tool_offset)
        return self._point(self.robot.body, TOOL_LINK, offset, inertial=False)

    def stretch(self) -> float:
        """World distance (m) between the constrained points; 0 when nothing is held."""
        if self.constraint is None:
            return 0.0
        tool = self._point(self.robot.body, TOOL_LINK, self._tool_local, inertial=True)
        held = self._point(self.body, self.link, self._target_local, inertial=True)
        return float(np.linalg.norm(tool - held))

    def update(self) -> None:
        """Attach or slip (see the class docstring)."""
        if self.constraint is not None:
            if self.stretch() > self.cfg.slip_distance:
                self.release()
            return
        tool, target = self.tool_point(), self.target_point()
        if math.dist(tool, target) > self.cfg.attach_distance:
            return
        # constraint pivots are given in each link's centre-of-mass (inertial) frame
        self._tool_local = self._local(self.robot.body, TOOL_LINK, tool)
        self._target_local = self._local(self.body, self.link, target)
        client = self.robot.client
        self.constraint = client.createConstraint(
            self.robot.body,
            TOOL_LINK,
            self.body,
            self.link,
            client.JOINT_POINT2POINT,
            [0.0, 0.0, 0.0],
            self._tool_local.tolist(),
            self._target_local.tolist(),
        )
        client.changeConstraint(self.constraint, maxForce=self.cfg.max_force)

    def release(self) -> None:
        """Open the gripper: remove the constraint if one is held."""
        if self.constraint is not None:
            self.robot.client.removeConstraint(self.constraint)
            self.constraint = None


# -- torque interface (Chapter 6) ------------------------------------------------------

#: Joint torque limits of the real KUKA LBR iiwa 7 R800 (datasheet, N m); the
#: `pybullet_data` URDF says 300 N m for every joint. The iiwa stands in for the thesis'
#: Kinova Jaco 2 (docs/rmp.md).
IIWA7_TORQUE_LIMITS = (176.0, 176.0, 110.0, 110.0, 110.0, 40.0, 40.0)


class LinkKinematics(NamedTuple):
    """Kinematics of links at the simulated state, all in the world frame.

    com: (L, 3) centre-of-mass positions, m; rotation: (L, 3, 3) link (URDF) frame
    orientations; frame: (L, 3) link (URDF) frame origins, m; velocity: (L, 3) linear
    velocities of the centres of mass, m/s; omega: (L, 3) angular velocities, rad/s;
    jacobian: (L, 6, 7) [linear; angular] Jacobians of the centres of mass;
    jdot_qdot: (L, 6) the velocity-product accelerations J'(q, q') q' of the centres of
    mass (finite difference of the Jacobian along q', see `Robot.link_kinematics`)."""

    com: NDArray[np.float64]
    rotation: NDArray[np.float64]
    frame: NDArray[np.float64]
    velocity: NDArray[np.float64]
    omega: NDArray[np.float64]
    jacobian: NDArray[np.float64]
    jdot_qdot: NDArray[np.float64]


def release_motors(robot: Robot) -> None:
    """Switch the joints to torque control: the default velocity motors (which PyBullet
    keeps at target 0 with the URDF's effort) get force 0, once after each reset. The
    URDF's joint damping (0.5 N m s) goes to 0 as well: on link 7 (inertia 4e-4 kg m^2)
    it exceeds what PyBullet's explicit step keeps stable at 240 Hz (b dt / I = 5 > 2;
    measured: the wrist ran away to PyBullet's 100 rad/s cap within a second)."""
    for j in range(N_JOINTS):
        robot.client.changeDynamics(robot.body, j, jointDamping=0.0)
    robot.client.setJointMotorControlArray(
        robot.body,
        list(range(N_JOINTS)),
        robot.client.VELOCITY_CONTROL,
        targetVelocities=[0.0] * N_JOINTS,
        forces=[0.0] * N_JOINTS,
    )


def cap_joint_speeds(robot: Robot) -> None:
    """Hold each joint's speed within the iiwa's limits (`Robot.velocity_limits`, its
    datasheet's), as its own controller does: PyBullet's solver clamps a joint's speed
    at `maxJointVelocity` (its default: 100 rad/s). Under torque control a light wrist
    otherwise spins up within a few steps (measured, Chapter 7's random actions: link 7
    at 6 rad/s, too fast to brake before its limit). Until the next `resetSimulation`."""
    for j, limit in enumerate(robot.velocity_limits):
        robot.client.changeDynamics(robot.body, j, maxJointVelocity=float(limit))


def command_torque(robot: Robot, torque: NDArray[np.float64]) -> NDArray[np.float64]:
    """Apply joint torques (7,) N m, clipped to `IIWA7_TORQUE_LIMITS`, for the next
    physics step (TORQUE_CONTROL holds for one `stepSimulation` only: call it every
    substep, after `release_motors`). Returns the clipped torques (7,)."""
    limit = np.asarray(IIWA7_TORQUE_LIMITS)
    tau = np.clip(np.asarray(torque, dtype=np.float64), -limit, limit)
    robot.client.setJointMotorControlArray(
        robot.body, list(range(N_JOINTS)), robot.client.TORQUE_CONTROL, forces=tau.tolist()
    )
    return tau


def mass_matrix(robot: Robot, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Joint-space inertia matrix M(q) (7, 7), kg m^2 (`calculateMassMatrix`)."""
    return np.asarray(robot.client.calculateMassMatrix(robot.body, list(map(float, q))))


def bias_forces(
    robot: Robot, q: NDArray[np.float64], qd: NDArray[np.float64]
) -> NDArray[np.float64]:
    """C(q, q') q' + g(q) (7,), N m: inverse dynamics at zero joint acceleration
    (`calculateInverseDynamics`), the torques that hold the arm's motion unaccelerated."""
    zero = [0.0] * N_JOINTS
    return np.asarray(
        robot.client.calculateInverseDynamics(
            robot.body, list(map(float, q)), list(map(float, qd)), zero
        )
    )


def point_jacobian(
    robot: Robot, link: int, local: NDArray[np.float64], q: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(6, 7) [linear; angular] Jacobian at q of a point fixed to `link`, given as
    PyBullet's `calculateJacobian` takes it: the point c + R (local - o), c and R the
    link's centre of mass and orientation, o its `localInertialFramePosition`
    (`getLinkState()[2]`); so `local = o` is the centre of mass (measured against finite
    differences of the positions: tests/sim/test_torque.py; `local = 0` is not the URDF
    frame origin)."""
    zero = [0.0] * N_JOINTS
    linear, angular = robot.client.calculateJacobian(
        robot.body, link, list(map(float, local)), list(map(float, q)), zero, zero
    )
    return np.array(linear + angular)


def link_kinematics(
    robot: Robot,
    links: list[int],
    q: NDArray[np.float64],
    qd: NDArray[np.float64],
    step: float = 1e-6,
    curvature: bool = True,
) -> LinkKinematics:
    """World kinematics of `links` at the simulated state (q (7,), qd (7,) as read from
    the simulator). J'q' is (J(q + h q') - J(q)) q' / h with h = `step` / max(|q'|, 1)
    (one more `calculateJacobian` per link; exact as h -> 0; 0 at rest), or 0 when not
    `curvature` (VICES does not use it)."""
    client = robot.client
    states = client.getLinkStates(robot.body, links, computeForwardKinematics=1)
    com = np.array([s[0] for s in states], dtype=np.float64)
    frame = np.array([s[4] for s in states], dtype=np.float64)
    rotation = np.array([np.reshape(robot.client.getMatrixFromQuaternion(s[5]), (3, 3))
                         for s in states])  # fmt: skip
    inertial = [s[2] for s in states]
    jacobian = np.array(
        [point_jacobian(robot, link, o, q) for link, o in zip(links, inertial, strict=True)]
    )
    velocity, omega = jacobian[:, :3] @ qd, jacobian[:, 3:] @ qd
    speed = float(np.max(np.abs(qd)))
    if speed == 0.0 or not curvature:
        jdot_qdot = np.zeros((len(links), 6))
    else:
        h = step / max(speed, 1.0)
        ahead = np.asarray(q) + h * np.asarray(qd)
        shifted = np.array(
            [point_jacobian(robot, link, o, ahead) for link, o in zip(links, inertial, strict=True)]
        )
        jdot_qdot = (shifted - jacobian) @ qd / h
    return LinkKinematics(com, rotation, frame, velocity, omega, jacobian, jdot_qdot)


def tool_arm_state(
    robot: Robot,
    kin: LinkKinematics,
    row: int,
    q: NDArray[np.float64],
    qd: NDArray[np.float64],
    tool_offset: float,
) -> ArmState:
    """The controllers' view of the arm (`control.osc.ArmState`) at q (7,), qd (7,): the
    tool point `tool_offset` m along the z axis of the link in row `row` of `kin` (the
    last link, `TOOL_LINK`), its (6, 7) Jacobian and J'q' (0 if `kin` has no curvature
    terms), and M(q), C q' + g of the arm alone."""
    rotation = kin.rotation[row]
    tool = kin.frame[row] + rotation[:, 2] * tool_offset
    r = tool - kin.com[row]
    jv, jw = kin.jacobian[row, :3], kin.jacobian[row, 3:]
    w, acc, alpha = kin.omega[row], kin.jdot_qdot[row, :3], kin.jdot_qdot[row, 3:]
    ee_jac = np.vstack([jv - skew(r) @ jw, jw])
    ee_jdot = np.concatenate([acc + cross(alpha, r) + cross(w, cross(w, r)), alpha])
    return ArmState(q, qd, mass_matrix(robot, q), bias_forces(robot, q, qd), tool, rotation,
                    ee_jac, ee_jdot)  # fmt: skip
