"""Joint axes of a kinematic tree from part geometry (thesis section 4.5.3 and beyond).

The thesis' heuristic (4.5.3): "the axes of rotation were determined from the
intersection of part bounding boxes and oriented in the world vertical direction"
(`method="thesis"`: axis through the centre of the intersection of the parent's and
the child's axis-aligned boxes, grown by `box_margin`, along `up`).

For a door covering its parent's whole front, the centre of that intersection is the
middle of the door, not its hinge, so the default `method="geometric"` goes further:

- Revolute (child C, parent P). The contact region is the set of C's points within
  `contact_radius` of P. Direction: the contact region's principal direction when the
  region is a strip (first / second singular value >= `elongation`: an open door
  touches its frame along the hinge), else `up` (the thesis' vertical). Origin: C's
  points are projected on the plane normal to the direction; the corners of their
  minimum-area rectangle are the candidate hinge lines. The two ends of the rectangle's
  side nearest the contact centroid face P; of those, the nearer one is the hinge,
  unless the contact is ambiguous (a closed door touches along its whole back): then the
  corner farther from the handle, which is C's children when it has any (a handle part
  of its own), else C's outermost points (the `protrusion` fraction of them farthest
  from P: a handle that is part of the door's link stands out of its front). The origin
  sits at the middle of C's extent along the axis.
- Prismatic. The candidates are +- the axes of C's minimum-volume oriented box
  (trimesh); each sweeps that box along itself by C's own length; the direction whose
  sweep holds the fewest of P's points wins (a drawer leaves through the open side of
  its cabinet), ties going to the axis best aligned with C's centroid minus P's
  centroid. Origin: C's centroid.
- Revolute sign (both methods): positive rotation moves C's centroid away from P's
  centroid, so joint limits (0, upper) open the part.
Fixed joints get no axis (None).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from artic.hierarchy.graph import check_segmented_cloud
from artic.objects.tree import JointAxis, KinematicTree

Array = NDArray[np.float64]


@dataclass(frozen=True)
class JointHeuristicConfig:
    """method: "geometric" (default, see module doc) or "thesis" (box intersection,
    vertical). up: the world vertical. contact_radius: metres, child points this close
    to the parent form the contact region. elongation: singular-value ratio above which
    the contact region is a strip that gives the hinge direction. ambiguity: relative
    difference of the two candidate hinge corners' distances to the contact centroid
    below which the contact does not decide. box_margin: metres, growth of the boxes of
    the thesis method. protrusion: fraction of a part's points farthest from its parent
    taken as its handle when it has no child parts."""

    method: Literal["geometric", "thesis"] = "geometric"
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    contact_radius: float = 0.02
    elongation: float = 2.5
    ambiguity: float = 0.25
    box_margin: float = 0.01
    protrusion: float = 0.05


def _unit(v: Array) -> Array:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _principal_axes(points: Array) -> tuple[Array, Array]:
    """Singular values (k,) and principal directions (k, d) (rows) of centred points."""
    centred = points - points.mean(axis=0)
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    return s, vt


def _box_axes(points: Array) -> Array:
    """(d, d) rows: the axes of the minimum-volume oriented box of (N, d) points, d = 2
    or 3 (trimesh; tighter than PCA on box-like parts), PCA when that fails."""
    from trimesh import bounds

    try:
        if points.shape[1] == 2:
            transform, _ = bounds.oriented_bounds_2D(points)
            return np.asarray(transform[:2, :2], dtype=np.float64)
        transform, _ = bounds.oriented_bounds(points)
        return np.asarray(transform[:3, :3], dtype=np.float64)
    except Exception:  # degenerate (flat, collinear) input: qhull fails
        return _principal_axes(points)[1]


#: the sides of the rectangle `corners` in revolute_axis: [lo, lo], [lo, hi], [hi, lo], [hi, hi]
_SIDES = ((0, 1), (2, 3), (0, 2), (1, 3))


def _segment_distance(point: Array, a: Array, b: Array) -> float:
    """Distance from `point` to the segment a-b (all (2,))."""
    ab = b - a
    t = float(np.clip((point - a) @ ab / max(float(ab @ ab), 1e-24), 0.0, 1.0))
    return float(np.linalg.norm(point - (a + t * ab)))


def outermost_points(child: Array, parent: Array, fraction: float) -> Array:
    """The `fraction` of the child's points farthest from the parent (at least one)."""
    distance, _ = cKDTree(parent).query(child, k=1)
    k = max(1, round(fraction * len(child)))
    return child[np.argsort(distance)[-k:]]


def contact_region(child: Array, parent: Array, radius: float) -> Array:
    """The child's points within `radius` of the parent (at least the 3 nearest)."""
    distance, _ = cKDTree(parent).query(child, k=1)
    close = distance <= radius
    if close.sum() < 3:
        close = np.zeros(len(child), dtype=bool)
        close[np.argsort(distance)[: min(3, len(child))]] = True
    return child[close]


def _orient_opening(direction: Array, origin: Array, child: Array, parent: Array) -> Array:
    """Flip `direction` so that positive rotation moves the child away from the parent."""
    c = child.mean(axis=0)
    motion = np.cross(direction, c - origin)
    return direction if float(motion @ (c - parent.mean(axis=0))) >= 0 else -direction


def thesis_axis(child: Array, parent: Array, cfg: JointHeuristicConfig) -> JointAxis:
    """Section 4.5.3: through the centre of the intersection of the (grown) bounding
    boxes, along the vertical. child, parent: (N, 3) metres."""
    m = cfg.box_margin
    lo = np.maximum(child.min(axis=0), parent.min(axis=0)) - m
    hi = np.minimum(child.max(axis=0), parent.max(axis=0)) + m
    origin = 0.5 * (lo + hi)  # for disjoint boxes: the middle of the gap
    direction = _orient_opening(_unit(np.asarray(cfg.up, dtype=np.float64)), origin, child, parent)
    return JointAxis(origin=origin, direction=direction)


def revolute_axis(
    child: Array,
    parent: Array,
    cfg: JointHeuristicConfig,
    away_from: Array | None = None,
) -> JointAxis:
    """Hinge of `child` on `parent` (both (N, 3), metres); `away_from` (3,): the centroid
    of the child's own children (a handle), used when the contact does not decide."""
    if cfg.method == "thesis":
        return thesis_axis(child, parent, cfg)
    contact = contact_region(child, parent, cfg.contact_radius)
    s, vt = _principal_axes(contact)
    strip = len(s) > 1 and s[0] >= cfg.elongation * max(float(s[1]), 1e-12)
    direction = _unit(vt[0]) if strip else _unit(np.asarray(cfg.up, dtype=np.float64))

    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = _unit(np.cross(direction, helper))
    v = np.cross(direction, u)
    plane = np.stack([u, v], axis=1)  # (3, 2)
    flat = child @ plane
    mean2 = flat.mean(axis=0)
    axes2 = _box_axes(flat)
    local = (flat - mean2) @ axes2.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    corners = corners @ axes2 + mean2  # back to plane coordinates
    target = contact.mean(axis=0) @ plane
    distance = np.linalg.norm(corners - target, axis=1)
    # the rectangle side nearest the contact faces P: its two ends are the candidates
    side = min(_SIDES, key=lambda e: _segment_distance(target, corners[e[0]], corners[e[1]]))
    near = np.array(sorted(side, key=lambda i: (distance[i], i)))
    d0, d1 = distance[near]
    pick = int(near[0])
    if away_from is not None and abs(d1 - d0) < cfg.ambiguity * max(d0 + d1, 1e-12):
        away = np.asarray(away_from, dtype=np.float64) @ plane
        pick = int(near[np.argmax(np.linalg.norm(corners[near] - away, axis=1))])
    along = child @ direction
    height = 0.5 * (along.min() + along.max())
    origin = plane @ corners[pick] + height * direction
    return JointAxis(origin=origin, direction=_orient_opening(direction, origin, child, parent))


def prismatic_axis(child: Array, parent: Array, cfg: JointHeuristicConfig) -> JointAxis:
    """Sliding direction of `child` out of `parent` (both (N, 3), metres)."""
    if cfg.method == "thesis":
        # The thesis gives no rule for prismatic joints; the same boxes decide: the
        # child's box axis best aligned with child minus parent centroid.
        vt = _box_axes(child)
        away = child.mean(axis=0) - parent.mean(axis=0)
        scores = vt @ away
        k = int(np.argmax(np.abs(scores)))
        return JointAxis(child.mean(axis=0), _unit(vt[k] * np.sign(scores[k] or 1.0)))
    center = child.mean(axis=0)
    vt = _box_axes(child)
    local_child = (child - center) @ vt.T
    lo, hi = local_child.min(axis=0), local_child.max(axis=0)
    local_parent = (parent - center) @ vt.T
    shrink = cfg.contact_radius
    away = _unit(center - parent.mean(axis=0))
    best: tuple[int, float] | None = None
    choice = vt[0]
    for k in range(3):
        others = [i for i in range(3) if i != k]
        inside = np.all(
            (local_parent[:, others] > lo[others] + shrink)
            & (local_parent[:, others] < hi[others] - shrink),
            axis=1,
        )
        length = hi[k] - lo[k]
        for sign in (1.0, -1.0):
            t = sign * local_parent[:, k]
            start = hi[k] if sign > 0 else -lo[k]
            blocked = int(np.sum(inside & (t > start + shrink) & (t < start + length + shrink)))
            key = (blocked, -float(sign * vt[k] @ away))
            if best is None or key < best:
                best, choice = key, sign * vt[k]
    return JointAxis(origin=center, direction=_unit(choice))


def estimate_axes(
    tree: KinematicTree,
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    cfg: JointHeuristicConfig | None = None,
) -> KinematicTree:
    """`tree` with an axis for every revolute and prismatic edge (None for fixed ones).

    points: (N, 3) metres; part_id: (N,) the tree's parts.
    """
    cfg = cfg or JointHeuristicConfig()
    num_parts = check_segmented_cloud(points, part_id)
    if num_parts != tree.num_parts:
        raise ValueError(f"part_id has {num_parts} parts, the tree {tree.num_parts}")
    pts = np.asarray(points, dtype=np.float64)
    ids = np.asarray(part_id)
    part_points = [pts[ids == p] for p in range(num_parts)]
    axes: list[JointAxis | None] = []
    for (parent, child), joint_type in zip(tree.edges, tree.joint_types, strict=True):
        if joint_type == "fixed":
            axes.append(None)
        elif joint_type == "prismatic":
            axes.append(prismatic_axis(part_points[child], part_points[parent], cfg))
        else:
            grandchildren = tree.children(child)
            handle = (
                np.concatenate([part_points[g] for g in grandchildren])
                if grandchildren
                else outermost_points(part_points[child], part_points[parent], cfg.protrusion)
            )
            axes.append(
                revolute_axis(part_points[child], part_points[parent], cfg, handle.mean(axis=0))
            )
    return tree.with_axes(tuple(axes))
