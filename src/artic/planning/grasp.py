"""EstimateGrasp and GraspPath of Algorithm 2 (thesis, Chapter 5).

End-effector convention: the tool frame's +z axis is the approach direction (pointing
from the hand into the object), as for a flange-mounted tool. A grasp is an end-effector
pose held fixed in the frame of the object link it acts on, so the end-effector path is
the link's forward kinematics along the object's plan composed with that offset.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from artic.geometry.transforms import axis_angle, invert, make_transform
from artic.objects.model import ArticulatedObject

GraspKind = Literal["handle", "push"]


@dataclass(frozen=True)
class Grasp:
    """An end-effector pose fixed to object link `link` (index into `model.links`).

    offset: (4, 4) end-effector pose in the link frame (ee = link_pose @ offset).
    kind: "handle" (hold the handle bar) or "push" (stand behind the part and push it
    along its motion, e.g. hit a ball). approach: (3,) unit approach direction in the
    link frame (the tool's +z axis).
    """

    link: int
    offset: NDArray[np.float64]
    kind: GraspKind
    approach: NDArray[np.float64]


def _frame(z_axis: NDArray[np.float64], x_hint: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) rotation with +z = `z_axis` and +x as close as possible to `x_hint`."""
    z = z_axis / np.linalg.norm(z_axis)
    x = x_hint - x_hint.dot(z) * z
    if np.linalg.norm(x) < 1e-6:  # hint parallel to z: any perpendicular
        x = np.eye(3)[int(np.argmin(np.abs(z)))]
        x = x - x.dot(z) * z
    x = x / np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def motion_direction(
    model: ArticulatedObject, link: int, configuration: NDArray[np.float64], eps: float = 1e-4
) -> NDArray[np.float64]:
    """(3,) unit world direction in which the centre of `link`'s mesh moves as the
    configuration increases along all its DoF (finite difference of f_O)."""
    q = np.asarray(configuration, dtype=np.float64)
    centre = _mesh_centre(model, link)
    a = (model.link_poses(q)[link] @ np.append(centre, 1.0))[:3]
    b = (model.link_poses(q + eps)[link] @ np.append(centre, 1.0))[:3]
    d = b - a
    norm = float(np.linalg.norm(d))
    if norm < 1e-12:
        raise ValueError(f"link {link} does not move with the object's joints")
    return d / norm


def _mesh_centre(model: ArticulatedObject, link: int) -> NDArray[np.float64]:
    v = model.links[link].mesh.vertices
    return 0.5 * (v.min(axis=0) + v.max(axis=0))


def estimate_grasp(
    model: ArticulatedObject,
    link: int,
    configuration: NDArray[np.float64],
    kind: GraspKind = "handle",
    standoff: float = 0.0,
    direction: float = 1.0,
    pitch: float = 0.0,
    lift: float = 0.0,
) -> Grasp:
    """EstimateGrasp (Algorithm 2, line 3) from the pose and box of `link`'s mesh.

    "handle": the link is a bar that stands out of a surface (artic's handles: link frame
    on the surface, bar in front of it). The outward direction n is the link-frame axis
    along which the mesh's box centre lies off the link origin; the grasp point is the
    middle of the bar's outer face, the tool approaches along -n from `standoff` metres
    in front of it, with its x axis along the bar (the box's longest side).
    "push" (a hitting pose behind a ball): d is the direction the link moves as q grows
    (times the sign of `direction`, i.e. the sign of q_O* - q_O). The tool's +z axis is
    d tilted `pitch` radians down towards world -z (about the horizontal axis d x up; 0:
    along d), its x axis as close to world up as possible. The contact point is where a
    plane with normal +z first touches the mesh from behind (the mesh's support point
    along -z); the tool point stands `standoff` metres behind it along -z and `lift`
    metres above it along the tool's x axis (the hand strikes with the lower part of its
    end face, so the arm clears what the link rests on). configuration: (dof,) the
    object's configuration.
    """
    q = np.asarray(configuration, dtype=np.float64)
    pose = model.link_poses(q)[link]
    v = model.links[link].mesh.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, extent = 0.5 * (lo + hi), hi - lo
    if kind == "handle":
        k = int(np.argmax(np.abs(centre)))
        if abs(centre[k]) < 1e-9:
            raise ValueError(f"link {link}: cannot tell which side of the handle faces out")
        n = np.sign(centre[k]) * np.eye(3)[k]
        bar = np.eye(3)[int(np.argmax(np.where(np.arange(3) == k, -np.inf, extent)))]
        others = [extent[i] for i in range(3) if i != k]
        point = centre + n * (0.5 * extent[k] - 0.5 * min(others) + standoff)
        # in the link frame; the hand approaches along -n
        rotation = _frame(-n, bar)
        offset = make_transform(rotation, point)
        approach = -n
    elif kind == "push":
        d_world = np.sign(direction or 1.0) * motion_direction(model, link, q)
        up_world = np.array([0.0, 0.0, 1.0])
        if pitch != 0.0:
            side = np.cross(d_world, up_world)
            if np.linalg.norm(side) < 1e-9:
                raise ValueError(f"link {link}: cannot pitch a push along the vertical")
            d_world = axis_angle(side / np.linalg.norm(side), -pitch) @ d_world
        d = pose[:3, :3].T @ d_world  # in the link frame
        rotation = _frame(d, pose[:3, :3].T @ up_world)
        half = float(np.max((centre - v) @ d))  # how far the mesh reaches back along -d
        point = centre - d * (half + standoff) + rotation[:, 0] * lift
        offset = make_transform(rotation, point)
        approach = d
    else:
        raise ValueError(f"grasp kind must be 'handle' or 'push', got {kind!r}")
    return Grasp(link=link, offset=offset, kind=kind, approach=approach)


def grasp_from_world_pose(
    model: ArticulatedObject,
    link: int,
    configuration: NDArray[np.float64],
    ee_pose: NDArray[np.float64],
    kind: GraspKind,
) -> Grasp:
    """The grasp that holds `ee_pose` (4, 4, world) fixed to `link` at `configuration`."""
    pose = model.link_poses(np.asarray(configuration, dtype=np.float64))[link]
    offset = invert(pose) @ ee_pose
    return Grasp(link=link, offset=offset, kind=kind, approach=offset[:3, 2].copy())


def grasp_path(
    model: ArticulatedObject, grasp: Grasp, object_path: ArrayLike
) -> NDArray[np.float64]:
    """GraspPath (Algorithm 2, line 4): end-effector poses along the object's plan.

    object_path: (K, dof) configurations of the object. Returns (K, 4, 4) world poses
    f_O(q_k)[link] @ grasp.offset.
    """
    path = np.asarray(object_path, dtype=np.float64)
    path = path.reshape(len(path), -1)
    return np.stack([model.link_poses(q)[grasp.link] @ grasp.offset for q in path])


def pregrasp_pose(ee_pose: NDArray[np.float64], distance: float) -> NDArray[np.float64]:
    """(4, 4) pose `distance` metres back from `ee_pose` along its approach (-z)."""
    out = np.array(ee_pose, dtype=np.float64, copy=True)
    out[:3, 3] -= distance * out[:3, 2]
    return out


def interpolate_poses(
    a: NDArray[np.float64], b: NDArray[np.float64], step: float
) -> NDArray[np.float64]:
    """(M, 4, 4) poses from `a` to `b` (both included) with positions at most `step`
    metres apart; orientation interpolated by slerp (scipy)."""
    from scipy.spatial.transform import Rotation, Slerp

    n = max(1, int(np.ceil(np.linalg.norm(b[:3, 3] - a[:3, 3]) / step)))
    s = np.linspace(0.0, 1.0, n + 1)
    rotations = Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]]))
    out = np.tile(np.eye(4), (n + 1, 1, 1))
    out[:, :3, :3] = Slerp([0.0, 1.0], rotations)(s).as_matrix()
    out[:, :3, 3] = a[:3, 3] + s[:, None] * (b[:3, 3] - a[:3, 3])
    return out
