"""Objects of the Chapter 5 tasks in a PyBullet client, built in memory (no files).

`load_articulated(client, obj)` turns an `artic.objects` `ArticulatedObject` into one
fixed-base multibody with `createCollisionShape` / `createMultiBody`: the body link as
a concave triangle mesh (static, so it collides with its real hollow shape), moving
parts and handles as convex hulls of their meshes (a drawer is then solid), inertial
frames from the link's exact mass properties (principal axes), joint limits, damping
and Coulomb friction (a velocity motor with target 0 whose largest force is the joint
friction, PyBullet's usual way). Index mapping (docs/objects.md): PyBullet joint j and
link j are `obj.joints[j]` and `obj.links[j + 1]`; the base is `obj.links[0]`.

`tball_model(scene)` is the t-ball task's kinematic model (a tee, and a ball on a
prismatic joint along world +y) and `load_tball` puts a static tee and a dynamic ball
in a client.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from artic.geometry.transforms import make_transform
from artic.objects.model import ArticulatedObject, Inertial, Joint, Link, TriangleMesh
from artic.objects.parts import mass_properties
from artic.sim.robot import pose_to_pybullet
from artic.sim.tasks import TBallScene


def _principal_frame(inertial: Inertial) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(principal moments (3,), (4, 4) inertial frame in the link frame)."""
    moments, axes = np.linalg.eigh(inertial.inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return np.maximum(moments, 1e-9), make_transform(axes, inertial.center_of_mass)


def _collision_shape(client: Any, mesh: TriangleMesh, concave: bool) -> int:
    vertices = mesh.vertices.tolist()
    if concave:
        return int(
            client.createCollisionShape(
                client.GEOM_MESH,
                vertices=vertices,
                indices=mesh.triangles.reshape(-1).tolist(),
                flags=client.GEOM_FORCE_CONCAVE_TRIMESH,
            )
        )
    return int(client.createCollisionShape(client.GEOM_MESH, vertices=vertices))


_JOINT_TYPES = {
    "revolute": "JOINT_REVOLUTE",
    "prismatic": "JOINT_PRISMATIC",
    "fixed": "JOINT_FIXED",
}


def load_articulated(client: Any, obj: ArticulatedObject, dynamic_base: bool = False) -> int:
    """Create `obj` as one multibody with its base fixed at `obj.base_pose`; returns its id.

    The root link is static (mass 0) unless `dynamic_base`. Joint damping, limits and
    friction come from each `Joint`; limits are enforced with a limit force of 10x the
    joint effort.
    """
    index = {link.name: i for i, link in enumerate(obj.links)}
    masses, shapes, positions, orientations = [], [], [], []
    inertial_positions, inertial_orientations, parents, types, axes = [], [], [], [], []
    moments_per_link = []
    for joint in obj.joints:
        link = obj.links[index[joint.child]]
        moments, frame = _principal_frame(link.inertial)
        moments_per_link.append(moments)
        masses.append(link.inertial.mass)
        shapes.append(_collision_shape(client, link.mesh, concave=False))
        position, quaternion = pose_to_pybullet(joint.origin)
        positions.append(position)
        orientations.append(quaternion)
        inertial_position, inertial_quaternion = pose_to_pybullet(frame)
        inertial_positions.append(inertial_position)
        inertial_orientations.append(inertial_quaternion)
        parents.append(index[joint.parent])  # 0 = base, k = PyBullet link k - 1
        types.append(getattr(client, _JOINT_TYPES[joint.type]))
        axes.append(joint.axis.tolist())
    base = obj.links[0]
    base_position, base_quaternion = pose_to_pybullet(obj.base_pose)
    body = int(
        client.createMultiBody(
            baseMass=base.inertial.mass if dynamic_base else 0.0,
            baseCollisionShapeIndex=_collision_shape(client, base.mesh, concave=not dynamic_base),
            basePosition=base_position,
            baseOrientation=base_quaternion,
            linkMasses=masses,
            linkCollisionShapeIndices=shapes,
            linkVisualShapeIndices=[-1] * len(shapes),
            linkPositions=positions,
            linkOrientations=orientations,
            linkInertialFramePositions=inertial_positions,
            linkInertialFrameOrientations=inertial_orientations,
            linkParentIndices=parents,
            linkJointTypes=types,
            linkJointAxis=axes,
        )
    )
    for j, (joint, moments) in enumerate(zip(obj.joints, moments_per_link, strict=True)):
        client.changeDynamics(body, j, localInertiaDiagonal=moments.tolist())
        if joint.type != "fixed":
            _joint_dynamics(client, body, j, joint)
    return body


def _joint_dynamics(client: Any, body: int, j: int, joint: Joint) -> None:
    lower, upper = joint.limits
    client.changeDynamics(
        body,
        j,
        jointDamping=joint.damping,
        jointLowerLimit=lower,
        jointUpperLimit=upper,
        jointLimitForce=10.0 * max(joint.effort, 1.0),
    )
    client.setJointMotorControl2(
        body, j, client.VELOCITY_CONTROL, targetVelocity=0.0, force=joint.friction
    )


def handle_grasp_point(mesh: TriangleMesh, thickness: float) -> NDArray[np.float64]:
    """Grasp point (3,) of a handle mesh in its link frame: the centre of the bar, i.e.
    the bounding-box centre in y and z and `thickness / 2` behind its front (min x)."""
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    centre = 0.5 * (lo + hi)
    return np.array([lo[0] + 0.5 * thickness, centre[1], centre[2]])


class TBallBodies(NamedTuple):
    """PyBullet ids of the t-ball scene: the static tee and the dynamic ball."""

    tee: int
    ball: int


def _cylinder_mesh(radius: float, height: float, sections: int = 16) -> TriangleMesh:
    import trimesh

    shape = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    shape.apply_translation([0.0, 0.0, height / 2])
    return TriangleMesh(np.asarray(shape.vertices), np.asarray(shape.faces, dtype=np.int32))


def _sphere_mesh(radius: float) -> TriangleMesh:
    import trimesh

    shape = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    return TriangleMesh(np.asarray(shape.vertices), np.asarray(shape.faces, dtype=np.int32))


def ball_start(scene: TBallScene) -> NDArray[np.float64]:
    """(3,) world position of the ball's centre at rest on the tee, m."""
    return np.array([scene.tee_x, scene.tee_y, scene.tee_height + scene.ball_radius])


def tball_model(scene: TBallScene) -> ArticulatedObject:
    """Kinematic model of the t-ball task: `links[0]` the tee (a cylinder, base pose at
    the tee's foot), `links[1]` the ball on a prismatic joint along world +y whose value
    is the ball's y displacement from its start (the task's object state)."""
    tee_mesh = _cylinder_mesh(scene.tee_radius, scene.tee_height)
    ball_mesh = _sphere_mesh(scene.ball_radius)
    ball_volume = 4.0 / 3.0 * np.pi * scene.ball_radius**3
    tee = Link("tee", "body", tee_mesh, mass_properties(tee_mesh, 500.0))
    ball = Link(
        "ball", "ball", ball_mesh, mass_properties(ball_mesh, scene.ball_mass / ball_volume)
    )
    joint = Joint(
        name="joint_0",
        type="prismatic",
        parent="tee",
        child="ball",
        origin=make_transform(
            translation=np.array([0.0, 0.0, scene.tee_height + scene.ball_radius])
        ),
        axis=np.array([0.0, 1.0, 0.0]),
        limits=scene.travel,
    )
    base = make_transform(translation=np.array([scene.tee_x, scene.tee_y, 0.0]))
    return ArticulatedObject("tball", (tee, ball), (joint,), base)


def load_tball(client: Any, scene: TBallScene) -> TBallBodies:
    """A static tee cylinder and a dynamic sphere resting on it (rolling friction and
    restitution from `scene`; the ground must get the same rolling friction)."""
    tee_shape = client.createCollisionShape(
        client.GEOM_CYLINDER,
        radius=scene.tee_radius,
        height=scene.tee_height,
    )
    tee = client.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=tee_shape,
        basePosition=[scene.tee_x, scene.tee_y, scene.tee_height / 2],
    )
    ball_shape = client.createCollisionShape(client.GEOM_SPHERE, radius=scene.ball_radius)
    ball = client.createMultiBody(
        baseMass=scene.ball_mass,
        baseCollisionShapeIndex=ball_shape,
        basePosition=ball_start(scene).tolist(),
    )
    client.changeDynamics(
        ball,
        -1,
        restitution=scene.ball_restitution,
        rollingFriction=scene.ball_rolling_friction,
        spinningFriction=scene.ball_rolling_friction,
    )
    return TBallBodies(int(tee), int(ball))


def load_ground(client: Any, rolling_friction: float = 0.0) -> int:
    """A static plane z = 0."""
    plane = client.createCollisionShape(client.GEOM_PLANE)
    ground = int(client.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=plane))
    client.changeDynamics(ground, -1, rollingFriction=rolling_friction)
    return ground
