"""A parallel-jaw gripper on the iiwa's flange, with tactile zones (Chapter 7, issue 21
part 1; thesis section 7.2.1, "Grasp controller Gamma").

Choice (docs/cip.md): a parallel jaw on the iiwa rather than pybullet_data's Panda. The
thesis' simulated experiments and its hardware both use the KUKA iiwa 7 (section 7.4),
and Chapters 5 and 6 already drive the iiwa in torque control (`sim/robot.py`,
`control/osc.py`); a Panda would bring a second arm model, other torque limits and other
joint limits into the same comparison.

The gripper is its own PyBullet multibody, built in code (no file): a palm box and two
fingers on prismatic joints, held on the flange by a fixed constraint. Each finger
travels 0 to `travel` (0.04 m) outward from the centre line, so the opening between the
pads is 2 q (0 to 0.08 m); Gamma drives both to 0 (closed) or `travel` (open) with at
most `force` (40 N) each. Gripper frame: the palm's centre; z along the flange axis (out
of the arm), fingers opening along y.

Its mass enters the controller's model (`payload`): the palm and fingers as one rigid
body fixed to link 7 (the fingers' travel moves their centre of mass by at most 4 cm
and is ignored), M += m Jv^T Jv + Jw^T I Jw and the gravity term += -m Jv^T g.

Tactile (`tactile`): the summed normal force of the contacts on each finger in 3 zones
along its length (tip, middle, base), 6 values, N: section 7.4's six touch sensors.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from artic.config.schemas import Strict
from artic.sim.robot import TOOL_LINK, Robot, point_jacobian

F64 = NDArray[np.float64]
ZONES = 3  # tactile zones per finger
FINGERS = (0, 1)  # the gripper body's links: +y finger, -y finger


class GripperConfig(Strict):
    """The parallel-jaw gripper (constants ours unless marked)."""

    flange: float = Field(0.045, ge=0, description="link 7 frame to the flange face along z, m")
    palm: tuple[float, float, float] = Field(
        (0.05, 0.12, 0.04), description="palm box extents along x, y, z, m"
    )
    palm_mass: float = Field(0.5, gt=0, description="palm mass, kg")
    finger_length: float = Field(0.05, gt=0, description="finger extent along z, m")
    finger_width: float = Field(0.02, gt=0, description="finger extent along x, m")
    finger_thickness: float = Field(0.01, gt=0, description="finger extent along y, m")
    finger_mass: float = Field(0.05, gt=0, description="mass of each finger, kg")
    travel: float = Field(0.04, gt=0, description="each finger's stroke, m (issue 21: 0-0.04)")
    force: float = Field(40.0, gt=0, description="largest force of each finger, N (issue 21)")
    speed: float = Field(0.2, gt=0, description="largest finger speed, m/s")
    friction: float = Field(1.5, ge=0, description="lateral friction of the fingers")

    @property
    def mass(self) -> float:
        """Palm and fingers, kg."""
        return self.palm_mass + 2 * self.finger_mass

    @property
    def tool_offset(self) -> float:
        """Link 7 frame to the tool point (between the finger pads' centres) along z, m."""
        return self.flange + self.palm[2] + self.finger_length / 2


class Payload(NamedTuple):
    """The gripper's share of the arm's model at q: mass (7, 7) kg m^2, bias (7,) N m."""

    mass: F64
    bias: F64


def _box_inertia(mass: float, extents: tuple[float, float, float]) -> F64:
    x, y, z = extents
    return mass / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])


class Gripper:
    """The gripper in one client, held on `robot`'s flange (module docstring)."""

    def __init__(
        self, client: Any, robot: Robot, cfg: GripperConfig | None = None, gravity: float = -9.81
    ) -> None:
        self.client, self.robot, self.gravity = client, robot, gravity
        self.cfg = cfg = cfg or GripperConfig()
        px, py, pz = cfg.palm
        half_finger = [cfg.finger_width / 2, cfg.finger_thickness / 2, cfg.finger_length / 2]
        palm = client.createCollisionShape(client.GEOM_BOX, halfExtents=[px / 2, py / 2, pz / 2])
        finger = client.createCollisionShape(client.GEOM_BOX, halfExtents=half_finger)
        # fingers hang below the palm; at q = 0 their pads meet on the centre line
        y0, z0 = cfg.finger_thickness / 2, pz / 2 + cfg.finger_length / 2
        self.body = int(
            client.createMultiBody(
                baseMass=cfg.palm_mass, baseCollisionShapeIndex=palm,
                linkMasses=[cfg.finger_mass] * 2, linkCollisionShapeIndices=[finger] * 2,
                linkVisualShapeIndices=[-1, -1],
                linkPositions=[[0.0, y0, z0], [0.0, -y0, z0]],
                linkOrientations=[[0, 0, 0, 1]] * 2,
                linkInertialFramePositions=[[0, 0, 0]] * 2,
                linkInertialFrameOrientations=[[0, 0, 0, 1]] * 2,
                linkParentIndices=[0, 0], linkJointTypes=[client.JOINT_PRISMATIC] * 2,
                linkJointAxis=[[0, 1, 0], [0, -1, 0]],
            )
        )  # fmt: skip
        for link in (-1, *FINGERS):
            client.changeDynamics(self.body, link, lateralFriction=cfg.friction)
        for link in range(client.getNumJoints(robot.body)):
            client.setCollisionFilterPair(robot.body, self.body, link, -1, 0)
        # the palm's centre in link 7's frame, and in its centre-of-mass frame (where
        # PyBullet's constraints are expressed)
        self.in_link = np.array([0.0, 0.0, cfg.flange + pz / 2])
        state = client.getLinkState(robot.body, TOOL_LINK)
        inv_pos, inv_orn = client.invertTransform(state[2], state[3])
        parent_pos, parent_orn = client.multiplyTransforms(
            inv_pos, inv_orn, self.in_link.tolist(), [0, 0, 0, 1]
        )
        self.follow()
        self.constraint = client.createConstraint(
            robot.body, TOOL_LINK, self.body, -1, client.JOINT_FIXED, [0, 0, 0],
            parent_pos, [0, 0, 0], parent_orn, [0, 0, 0, 1],
        )  # fmt: skip
        client.changeConstraint(self.constraint, maxForce=1e5)
        self._inertia = _box_inertia(cfg.palm_mass, cfg.palm)
        self.target = cfg.travel
        self.set_opening(cfg.travel)

    # -- kinematic resets ----------------------------------------------------------------

    def palm_pose(self) -> tuple[list[float], list[float]]:
        """Where the palm belongs on the flange now: (position, quaternion x, y, z, w)."""
        state = self.client.getLinkState(self.robot.body, TOOL_LINK, computeForwardKinematics=1)
        pos, orn = self.client.multiplyTransforms(
            state[4], state[5], self.in_link.tolist(), [0, 0, 0, 1]
        )
        return list(pos), list(orn)

    def follow(self) -> None:
        """Put the gripper on the flange, at rest (after a kinematic reset of the arm)."""
        pos, orn = self.palm_pose()
        self.client.resetBasePositionAndOrientation(self.body, pos, orn)
        self.client.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0])

    def set_opening(self, q: float) -> None:
        """Kinematic reset of both fingers to travel q (m) and the motor target to match."""
        q = float(np.clip(q, 0.0, self.cfg.travel))
        for link in FINGERS:
            self.client.resetJointState(self.body, link, q, 0.0)
        self.target = q
        self._drive()

    # -- Gamma -------------------------------------------------------------------------

    def command(self, close: bool) -> None:
        """Gamma: drive both fingers closed (to 0) or open (to `travel`), at most `force`."""
        self.target = 0.0 if close else self.cfg.travel
        self._drive()

    def _drive(self) -> None:
        cfg = self.cfg
        for link in FINGERS:
            self.client.setJointMotorControl2(
                self.body, link, self.client.POSITION_CONTROL, targetPosition=self.target,
                force=cfg.force, maxVelocity=cfg.speed,
            )  # fmt: skip

    @property
    def closing(self) -> bool:
        return self.target < self.cfg.travel / 2

    def width(self) -> float:
        """Opening between the finger pads, m (the sum of the two fingers' travel)."""
        return float(sum(self.client.getJointState(self.body, j)[0] for j in FINGERS))

    # -- sensing -----------------------------------------------------------------------

    def tactile(self, exclude: tuple[int, ...] = ()) -> F64:
        """(6,) summed normal contact force on each finger (the +y finger, then the -y
        one) in 3 zones along its length (tip, middle, base), N; contacts with the bodies
        in `exclude` (the robot itself) are not touches."""
        cfg, client = self.cfg, self.client
        out = np.zeros(2 * ZONES)
        for k, link in enumerate(FINGERS):
            contacts = client.getContactPoints(bodyA=self.body, linkIndexA=link)
            if not contacts:
                continue
            state = client.getLinkState(self.body, link, computeForwardKinematics=1)
            inv_pos, inv_orn = client.invertTransform(state[4], state[5])
            for contact in contacts:
                if contact[2] in exclude or contact[8] > 0.0:
                    continue
                local, _ = client.multiplyTransforms(inv_pos, inv_orn, contact[5], [0, 0, 0, 1])
                # local z runs from -L/2 (palm side) to +L/2 (tip)
                along = (cfg.finger_length / 2 - local[2]) / cfg.finger_length  # 0 tip, 1 base
                zone = int(np.clip(np.floor(along * ZONES), 0, ZONES - 1))
                out[k * ZONES + zone] += float(contact[9])
        return out

    # -- the controller's model ----------------------------------------------------------

    def payload(self, q: F64) -> Payload:
        """The gripper's mass as a rigid body on link 7 at q (7,): its share of M and of
        the gravity term (module docstring); Coriolis terms of the payload are left out."""
        jac = point_jacobian(self.robot, TOOL_LINK, self.in_link, q)
        jv, jw = jac[:3], jac[3:]
        state = self.client.getLinkState(self.robot.body, TOOL_LINK, computeForwardKinematics=1)
        rotation = np.reshape(self.client.getMatrixFromQuaternion(state[5]), (3, 3))
        inertia = rotation @ self._inertia @ rotation.T
        mass = self.cfg.mass * jv.T @ jv + jw.T @ inertia @ jw
        return Payload(mass, -self.cfg.mass * jv.T @ np.array([0.0, 0.0, self.gravity]))
