"""The yaw of a user's scan: which way its front faces (issue 18, item 4).

`infer_hierarchy` works in artic's object frame (docs/objects.md): metres, z up, the
front (doors, drawers, the seat's front) facing -x. A user's scan is in metres with z up
but faces any direction. `canonical_yaw(points)` estimates the rotation about z that
takes the object frame to the scan's frame, so that `rotate_z(points, -yaw)` is the scan
in the object frame and `rotate_z(results, yaw)` brings points, axes and origins back.

1. Dominant vertical planes, up to 90 degrees. Point normals by local PCA over the
   `neighbours` nearest points (scipy's cKDTree); the normals of flat neighbourhoods
   that are nearly horizontal vote with their azimuth modulo 90 degrees in a circular
   histogram (1-degree bins, smoothed); the peak, refined by the circular mean of the
   votes within `refine_deg` of it, is a first angle. Normals near the T-junctions of
   thin panels are a few degrees off, so the angle is then refined within `search_deg`
   by the sharpness of the cloud's projections on the two turned axes (walls aligned
   with an axis pile up in one bin: `projection_sharpness`); that is the plane angle
   `plane_yaw` in [-45, 45) degrees. `plane_confidence`: the share of the votes within
   `refine_deg` of the histogram's peak, rescaled so that evenly spread azimuths give 0
   and a perfect box 1.
2. The front, among the four sides of the aligned cloud: each side gets a score, a
   weighted sum of the cloud's profile towards it (`side_features`: where along the
   side's axis the points lie, all of them and those whose normals are along that axis,
   across it, or vertical). A front has door and drawer faces and handles across its
   axis at its end and ajar doors reaching out of the body; a back is one flat panel,
   or nothing in a scan that sees the front most (artic's noisy scans: views within 70
   degrees of it). The weights (`PROFILE_WEIGHTS`) are a multinomial logistic regression
   over the four sides fitted on artic's training scans of a category
   (`scripts/fit_front_weights.py`), so `front_confidence` is the softmax probability of
   the chosen side. Where the geometry says nothing about the front (a closed box), it
   is a guess. Storage furniture's weights are the default; office chairs and lamps have
   their own (`CATEGORY_YAW`), which find the side their scans were taken from.

Office chairs (`CATEGORY_YAW`, `yaw_config`): the seat and back swivel, so step 1 reads
only the legs (the lowest `plane_band` of the height), and step 2 uses weights fitted on
the chairs' noisy training scans (`profile="office_chair"`). A swivelling chair's four
equal legs do not say which side is its front, but a scan does say which side it was
taken from, and the segmenter was trained on scans taken from the object frame's front
(-x): on its withheld noisy scans turned by exact quarter turns, mAP@0.5 0.905 unturned
against 0.885-0.898 turned (docs/hierarchy.md, "Scan frame and yaw").

Pure numpy/scipy, deterministic: the same points give the same estimate (clouds above
`max_points` are thinned by a fixed stride, no random draw).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from artic.errors import InputError
from artic.geometry.transforms import rot_z
from artic.objects.tree import JointAxis, KinematicTree

#: fewer points than this cannot show planes (InputError)
MIN_POINTS = 32

#: the outward directions of the four sides of an aligned cloud, in the order of the
#: quarter turns k = 0..3 that bring each to -x (side k faces rot_z(k * 90 deg) @ -x)
_SIDES = np.array([[-1.0, 0.0], [0.0, -1.0], [1.0, 0.0], [0.0, 1.0]])


@dataclass(frozen=True)
class YawConfig:
    """Settings of `canonical_yaw` (their meaning in the module doc).

    neighbours: points per normal (local PCA). max_points: larger clouds are thinned by a
    fixed stride first. flatness: a normal votes when its neighbourhood's smallest PCA
    eigenvalue is below this times the middle one (a thin panel's two faces still give
    the panel's normal) and horizontal: its horizontal component is at least this (1 =
    exactly horizontal). refine_deg: votes this close to the histogram's peak refine it.
    search_deg, bin_m: the projection-sharpness search around the normals' angle, and
    its bin (metres).
    """

    neighbours: int = 16
    max_points: int = 10_000
    flatness: float = 0.3
    horizontal: float = 0.9
    refine_deg: float = 5.0
    search_deg: float = 3.0
    bin_m: float = 0.003
    #: the planes are read from the points in this share of the height, from the bottom
    #: (1: all of them; an office chair's 0.12: its legs, since its seat swivels)
    plane_band: float = 1.0
    #: whose fitted weights choose the front among the four sides (`PROFILE_WEIGHTS`)
    profile: Literal["storage_furniture", "office_chair", "lamp"] = "storage_furniture"


#: the settings of the yaw step per category, where they differ from `YawConfig()`: an
#: office chair's legs are its only planes that stay in the object frame's axes (its
#: seat and back swivel); a chair's and a lamp's front is the side the scan was taken
#: from, which their own weights tell (docs/hierarchy.md)
CATEGORY_YAW = {
    "office_chair": YawConfig(plane_band=0.12, profile="office_chair"),
    "lamp": YawConfig(profile="lamp"),
}


def yaw_config(category: str) -> YawConfig:
    """The yaw step's settings for scans of `category` (`CATEGORY_YAW`, else defaults)."""
    return CATEGORY_YAW.get(category, YawConfig())


class YawEstimate(NamedTuple):
    """Where a scan's front faces.

    yaw: radians in [-pi, pi): the scan is the object frame rotated by `yaw` about z
    (scan = rotate_z(object, yaw)). plane_yaw: radians in [-pi/4, pi/4), the dominant
    vertical planes' angle (yaw modulo 90 degrees). plane_confidence, front_confidence:
    in [0, 1] (module doc). side_probabilities: (4,) p(front) of the sides facing
    rot_z(plane_yaw + k pi/2) @ -x, k = 0..3; the chosen one is yaw - plane_yaw.
    """

    yaw: float
    plane_yaw: float
    plane_confidence: float
    front_confidence: float
    side_probabilities: NDArray[np.float64]

    @property
    def yaw_deg(self) -> float:
        return math.degrees(self.yaw)

    def to_dict(self) -> dict[str, float | list[float]]:
        """The JSON record (degrees, rounded)."""
        return {
            "yaw_deg": round(self.yaw_deg, 3),
            "plane_yaw_deg": round(math.degrees(self.plane_yaw), 3),
            "plane_confidence": round(self.plane_confidence, 4),
            "front_confidence": round(self.front_confidence, 4),
            "side_probabilities": [round(float(p), 4) for p in self.side_probabilities],
        }


def _checked(points: NDArray[np.floating]) -> NDArray[np.float64]:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"points: expected an (N, 3) array, got shape {pts.shape}")
    if len(pts) < MIN_POINTS:
        raise InputError(
            f"points: {len(pts)} points are too few to find the scan's yaw (at least {MIN_POINTS})"
        )
    if not np.isfinite(pts).all():
        raise InputError("points: NaN or infinite coordinates")
    return pts


def rotate_z(points: NDArray[np.floating], angle: float) -> NDArray[np.float64]:
    """(N, 3) points (or (3,) one point or vector) rotated by `angle` radians about the z
    axis through the origin; rotate_z(rotate_z(p, a), -a) == p up to rounding."""
    pts = np.asarray(points, dtype=np.float64)
    return pts @ rot_z(angle).T


def rotate_tree_z(tree: KinematicTree, angle: float) -> KinematicTree:
    """The tree with its joint axes (origins and directions) rotated by `angle` about z;
    a tree without axes, or a fixed joint's None, is unchanged."""
    if tree.axes is None:
        return tree
    axes = tuple(
        None
        if axis is None
        else JointAxis(
            origin=rotate_z(axis.origin, angle),
            direction=rotate_z(axis.direction, angle),
        )
        for axis in tree.axes
    )
    return tree.with_axes(axes)


def _thinned(pts: NDArray[np.float64], max_points: int) -> NDArray[np.float64]:
    if len(pts) <= max_points:
        return pts
    return pts[np.linspace(0, len(pts) - 1, max_points).round().astype(np.int64)]


def point_normals(
    points: NDArray[np.float64], neighbours: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unoriented unit normals (N, 3) by local PCA over each point's `neighbours`
    nearest points, and the flatness (N,) of each neighbourhood: its smallest PCA
    eigenvalue over the middle one (0 on a plane, 1 where no direction stands out, and
    for neighbourhoods without a surface: collinear or repeated points)."""
    k = min(neighbours, len(points))
    _, idx = cKDTree(points).query(points, k)
    local = points[idx] - points[idx].mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", local, local)
    eigenvalues, eigenvectors = np.linalg.eigh(cov)
    smallest, middle, largest = eigenvalues[:, 0], eigenvalues[:, 1], eigenvalues[:, 2]
    surface = middle > 1e-9 * largest + 1e-30
    flatness = np.where(surface, smallest / np.where(surface, middle, 1.0), 1.0)
    return eigenvectors[:, :, 0], flatness


def _plane_yaw(
    azimuth: NDArray[np.float64], weight: NDArray[np.float64], refine_deg: float
) -> tuple[float, float]:
    """The dominant normal azimuth modulo 90 degrees (radians, [-pi/4, pi/4)) and its
    confidence (module doc, step 1)."""
    if weight.sum() <= 0:
        return 0.0, 0.0
    quarter = np.degrees(azimuth) % 90.0  # [0, 90)
    hist, _ = np.histogram(quarter, bins=90, range=(0.0, 90.0), weights=weight)
    offsets = np.arange(-4, 5)
    kernel = np.exp(-0.5 * (offsets / 1.5) ** 2)
    smooth = sum(k * np.roll(hist, -o) for k, o in zip(kernel, offsets, strict=True))
    peak = float(np.argmax(smooth)) + 0.5
    delta = (quarter - peak + 45.0) % 90.0 - 45.0  # signed distance to the peak, degrees
    near = np.abs(delta) <= refine_deg
    angle4 = np.radians(4.0 * delta[near])
    w = weight[near]
    mean4 = math.atan2(float((w * np.sin(angle4)).sum()), float((w * np.cos(angle4)).sum()))
    share = float(w.sum() / weight.sum())
    uniform = 2.0 * refine_deg / 90.0
    confidence = min(max((share - uniform) / (1.0 - uniform), 0.0), 1.0)
    plane = (peak + math.degrees(mean4) / 4.0 + 45.0) % 90.0 - 45.0
    return math.radians(plane), confidence


def projection_sharpness(xy: NDArray[np.float64], angle: float, bin_m: float) -> float:
    """How sharply (N, 2) points pile up on lines along the axes turned by `angle`: the
    sum of squared counts of their projections on both axes, in bins of `bin_m` metres
    (linear binning, so the score is continuous in the angle). Walls aligned with the
    axes give spikes; turned away, they smear."""
    c, s = math.cos(angle), math.sin(angle)
    total = 0.0
    for u in (xy[:, 0] * c + xy[:, 1] * s, xy[:, 1] * c - xy[:, 0] * s):
        f = (u - u.min()) / bin_m
        i = np.floor(f).astype(np.int64)
        w = f - i
        size = int(i.max()) + 2
        counts = np.bincount(i, 1.0 - w, minlength=size) + np.bincount(i + 1, w, minlength=size)
        total += float(np.dot(counts, counts))
    return total


def _sharpest(xy: NDArray[np.float64], start: float, cfg: YawConfig) -> float:
    """The angle within `cfg.search_deg` of `start` with the sharpest projections: a
    0.25-degree grid, then a 0.025-degree grid around its best (first best on ties)."""
    best = start
    for half, step in ((cfg.search_deg, 0.25), (0.25, 0.025)):
        grid = best + np.radians(np.arange(-half, half + step / 2, step))
        scores = [projection_sharpness(xy, float(a), cfg.bin_m) for a in grid]
        best = float(grid[int(np.argmax(scores))])
    return (best + math.pi / 4) % (math.pi / 2) - math.pi / 4


#: where a side's profile is read: `along` (the coordinate towards the side over the
#: half extent, clipped to +-1.25) falls into these 8 bins
PROFILE_EDGES = np.array([-1.25, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.25])

#: weights of `side_features` (4 groups x 8 bins) in a side's front score: multinomial
#: logistic regression (softmax over the four sides, L2 1e-3 on standardised features)
#: fitted on the 1,080 training scans of artic's storage furniture (clean and noisy),
#: each turned by a random yaw (docs/hierarchy.md, "Scan frame and yaw")
FRONT_WEIGHTS = np.array(
    [
        [0.1451, -5.749, 0.4545, 2.15, 11.68, 2.833, -1.184, -2.418],
        [-2.207, 26.79, 10.32, 4.994, -23.23, -10.28, 13.07, -0.8411],
        [48.45, 5.609, 14.18, 12.47, 24.32, -14.39, -16.08, -68.85],
        [32.99, 31.73, 47.75, 27.14, 31.9, -23.39, -47.27, -101.2],
    ]
)

#: the same fitted on the office chair's noisy training scans (its settings: the planes
#: of its legs), 6 poses of each of its 180 training objects taken with the Kinect and
#: again with its 128-pixel camera (`camera=kinect_v1_128`), each turned by a random yaw;
#: their front is the side they were taken from (`scripts/fit_front_weights.py`;
#: docs/hierarchy.md, "Scan frame and yaw")
CHAIR_FRONT_WEIGHTS = np.array(
    [
        [-7.166, 2.506, -3.16, 4.718, -6.368, -0.2417, -1.288, 7.607],
        [7.588, -8.072, 8.201, -97.42, 70.47, -6.145, 3.686, -1.897],
        [43.9, -16.73, -22.27, 78.06, -38.15, -8.608, 11.49, -19.02],
        [109.9, -100.4, -114.6, 141.5, -75.18, 85.83, 15.2, -132],
    ]
)

#: the same fitted on the lamp's noisy training scans, 6 poses of each of its 180 training
#: objects taken with the Kinect and with its 128-pixel camera, each turned by a random
#: yaw: a lamp's front is the side it was scanned from too (docs/hierarchy.md)
LAMP_FRONT_WEIGHTS = np.array(
    [
        [-31.79, 18.83, -0.2677, 2.462, -0.5246, -3.384, -5.616, 21.18],
        [-42.45, -36.43, -8.272, -0.143, 34.41, 17.26, 15.8, -5.709],
        [133.2, -30.3, 17.69, 4.487, -9.806, 11.61, 20.73, -19.76],
        [51.41, -35.23, 2.16, -6.057, 8.551, -1.001, -2.054, -15.86],
    ]
)

#: `YawConfig.profile` -> its weights
PROFILE_WEIGHTS = {
    "storage_furniture": FRONT_WEIGHTS,
    "office_chair": CHAIR_FRONT_WEIGHTS,
    "lamp": LAMP_FRONT_WEIGHTS,
}


def side_features(
    aligned: NDArray[np.float64], normals: NDArray[np.float64], cfg: YawConfig
) -> NDArray[np.float64]:
    """(4, 4, 8) the profile of an axis-aligned cloud towards each side (sides in
    `_SIDES` order): with `along` the coordinate towards the side from the centre of the
    cloud's (0.5, 99.5) percentile box, over its half extent along that axis (clipped to
    +-1.25), the share of all points in each `PROFILE_EDGES` bin of `along`, among
    (0) all points, (1) points whose normal is along the side's axis (|n . side| > 0.9),
    (2) along the other horizontal axis, (3) vertical. A front has door and drawer faces
    and handles across its axis at its end, ajar doors along it beyond the body; a back
    is one flat panel, or nothing in a scan that sees the front."""
    xy = aligned[:, :2]
    lo, hi = np.percentile(xy, 0.5, axis=0), np.percentile(xy, 99.5, axis=0)
    centred = xy - 0.5 * (lo + hi)
    half = np.maximum(0.5 * (hi - lo), 1e-6)
    n_xy = normals[:, :2]
    vertical = np.abs(normals[:, 2]) > 0.9
    everything = np.ones(len(xy), dtype=bool)
    features = np.zeros((4, 4, len(PROFILE_EDGES) - 1))
    for k, side in enumerate(_SIDES):
        across = _SIDES[(k + 1) % 4]
        along = np.clip(centred @ side / half[int(abs(side[1]))], -1.25, 1.25)
        kinds = (everything, np.abs(n_xy @ side) > 0.9, np.abs(n_xy @ across) > 0.9, vertical)
        for g, mask in enumerate(kinds):
            counts, _ = np.histogram(along[mask], bins=PROFILE_EDGES)
            features[k, g] = counts / len(xy)
    return features


def front_probabilities(
    features: NDArray[np.float64], weights: NDArray[np.float64] = FRONT_WEIGHTS
) -> NDArray[np.float64]:
    """(4,) p(side k is the front) from `side_features` (4, 4, 8): a softmax of the
    sides' scores, each the sum of its features times `weights` (4, 8), in float64."""
    scores = np.einsum("kgb,gb->k", features, weights)
    e = np.exp(scores - scores.max())
    return np.asarray(e / e.sum(), dtype=np.float64)


class FrontExample(NamedTuple):
    """One training example of the front step: `side_features` (4, 4, 8) of a scan
    turned by a known yaw, and the side that is its front (0..3, `_SIDES` order)."""

    features: NDArray[np.float64]
    front: int


def front_example(
    points: NDArray[np.floating], yaw: float, cfg: YawConfig | None = None
) -> FrontExample:
    """The front step's example from a scan in the object frame (front towards -x),
    turned by `yaw` radians: its features after the plane step, as `canonical_yaw` sees
    them, and the side its front then faces."""
    aligned = _aligned(rotate_z(_checked(points), yaw), cfg or YawConfig())
    front = round(((yaw - aligned.plane) % (2 * math.pi)) / (math.pi / 2)) % 4
    return FrontExample(aligned.features, int(front))


def fit_front_weights(
    features: NDArray[np.float64], fronts: NDArray[np.integer], l2: float = 1e-3
) -> NDArray[np.float64]:
    """`FRONT_WEIGHTS` (4, 8) from S examples: features (S, 4, 4, 8), fronts (S,). A
    multinomial logistic regression over the four sides with one weight per feature
    shared by the sides, fitted on standardised features (L-BFGS, L2 penalty `l2`) and
    returned for raw features (the means shift every side's score alike)."""
    from scipy.optimize import minimize  # fitting only: inference never loads it

    flat = features.reshape(len(features), 4, -1)
    sd = flat.reshape(-1, flat.shape[2]).std(axis=0) + 1e-9
    mean = flat.reshape(-1, flat.shape[2]).mean(axis=0)
    x = (flat - mean) / sd
    rows = np.arange(len(fronts))

    def loss(w: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        scores = x @ w
        scores = scores - scores.max(axis=1, keepdims=True)
        p = np.exp(scores)
        p /= p.sum(axis=1, keepdims=True)
        value = -np.log(p[rows, fronts]).mean() + l2 * float(w @ w)
        p[rows, fronts] -= 1.0
        grad = np.einsum("sk,skf->f", p, x) / len(fronts) + 2 * l2 * w
        return float(value), grad

    result = minimize(loss, np.zeros(flat.shape[2]), jac=True, method="L-BFGS-B")
    return np.asarray(result.x / sd, dtype=np.float64).reshape(features.shape[2:])


def _plane_angle(
    pts: NDArray[np.float64],
    normals: NDArray[np.float64],
    flatness: NDArray[np.float64],
    cfg: YawConfig,
) -> tuple[float, float]:
    """Step 1 of the module doc: the plane angle (radians, [-pi/4, pi/4)) and its
    confidence."""
    horizontal = np.hypot(normals[:, 0], normals[:, 1])
    votes = (flatness < cfg.flatness) & (horizontal >= cfg.horizontal)
    azimuth = np.arctan2(normals[votes, 1], normals[votes, 0])
    coarse, confidence = _plane_yaw(azimuth, horizontal[votes], cfg.refine_deg)
    return _sharpest(pts[:, :2], coarse, cfg), confidence


def _band(pts: NDArray[np.float64], low: float, high: float) -> NDArray[np.bool_]:
    """(N,) the points whose height lies in [low, high] of the cloud's z extent (shares)."""
    z = pts[:, 2]
    bottom, height = float(z.min()), float(np.ptp(z))
    return np.asarray((z >= bottom + low * height) & (z <= bottom + high * height))


class _Aligned(NamedTuple):
    plane: float  # the plane angle (radians, [-pi/4, pi/4))
    plane_confidence: float
    features: NDArray[np.float64]  # `side_features` (4, 4, 8) of the cloud turned by -plane


def _aligned(pts: NDArray[np.float64], cfg: YawConfig) -> _Aligned:
    """Step 1 on a checked cloud (thinned here), and the front step's features."""
    pts = _thinned(pts, cfg.max_points)
    normals, flatness = point_normals(pts, cfg.neighbours)
    band = _band(pts, 0.0, cfg.plane_band)
    if band.sum() < MIN_POINTS:
        band[:] = True
    plane, plane_confidence = _plane_angle(pts[band], normals[band], flatness[band], cfg)
    features = side_features(rotate_z(pts, -plane), rotate_z(normals, -plane), cfg)
    return _Aligned(plane, plane_confidence, features)


def canonical_yaw(points: NDArray[np.floating], cfg: YawConfig | None = None) -> YawEstimate:
    """The yaw of a scan: `rotate_z(points, -estimate.yaw)` is it in the object frame.

    points: (N, 3) metres, z up, N >= MIN_POINTS, finite (InputError otherwise).
    """
    cfg = cfg or YawConfig()
    aligned = _aligned(_checked(points), cfg)
    probabilities = front_probabilities(aligned.features, PROFILE_WEIGHTS[cfg.profile])
    front = int(np.argmax(probabilities))
    plane = aligned.plane
    yaw = (plane + front * math.pi / 2 + math.pi) % (2 * math.pi) - math.pi
    return YawEstimate(yaw, plane, aligned.plane_confidence, float(probabilities[front]),
                       probabilities)  # fmt: skip
