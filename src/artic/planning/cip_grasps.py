"""The grasp candidates G and the grasp initiation set I_c of a CIP, and the head's choice
of a start configuration (thesis section 7.2.1, "Grasp initiation set I_c"; Algorithm 3,
lines 1-3 and 6-9; issue 21 part 4).

Lines 1-2, v <- observe_scene(), G <- get_grasp_candidates(v): the object is scanned
(`render/scan.py`'s fused labelled scan, sensor model included), the cloud cut down to
the part the skill manipulates (`handle_0`), normals estimated by Open3D and turned
toward the cameras that saw each point (`part_cloud`). Grasps are sampled on it the way
ten Pas et al. (2017) sample theirs, from a point and its normal (`sample_grasps`):

- approach (the tool's z) into the surface, along the inward normal made perpendicular
  to the bar's axis (the cloud's principal direction), then turned about that axis by a
  random tilt; a grasp whose approach ends up more than `max_approach_deg` from -n is
  drawn again;
- the fingers (the tool's y, the closing direction) across the bar: y = z x axis, its
  sign drawn (the wrist turned half a turn is another arm configuration);
- the tool point (the centre between the finger pads, `GripperConfig.tool_offset` along
  the flange axis) half a bar thickness behind the sampled point along the inward
  normal: on the bar's centre line, so the pads (5 cm long, centred on the tool point)
  cover the 1.5 cm section with 1.75 cm to spare on each side and the open jaws (8 cm)
  clear it by 3.25 cm on either side.

Each candidate is then checked with the object at its nominal pose (the centre of the
episodes' jitter; `build_initiation_set` runs its own environment of the task) by
filters, each its own function, all deterministic:
reachability (`reachable_solutions`: IK from 16 seeds, the home configuration and 15
drawn within the joint limits, keeping distinct solutions that reach the pose and stay
clear of B's joint-limit threshold), collision (`in_collision`: the arm at the solution
with the gripper open, kinematically, against the object, the ground and itself), and
the grasp itself (`holds_handle`: the environment reset at the solution with Gamma
closing, both fingers must feel the handle; section 7.4: "filtered for collision, IK
feasibility, and successful contact with the handle"). Each kept solution is scored
w P (Yoshikawa's manipulability times Eq. 7.1, `planning/grasp_score.py`). What passes
is the domain of I_c: `InitiationSet`, the grasps in the object's frame with their
solutions and scores and a UCB1 bandit over them (line 3: I_c(g) <- 0), written as
initiation_set.json (`to_json` / `from_json`).

Lines 6-9 (`select_start`) under the settings of section 7.3: Head and Safety take a
random grasp and its first IK solution (naive IK; Safety differs only by the
environment's envelope), MV a random grasp and its best-scored solution, CIP the
bandit's grasp and its best-scored solution. The episode's object pose is jittered, so
the stored grasp is moved with the object and IK solved again, warm-started from the
stored solution (falling back to the next one); the outcome goes back to the bandit
(line 14, `report_outcome`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, FiniteFloat, ValidationError

from artic.config.schemas import Strict
from artic.control.osc import skew
from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics
from artic.learning.bandits import UCB1, BanditState
from artic.objects.model import ArticulatedObject
from artic.objects.spec import PartsConfig
from artic.planning.grasp_score import GraspScoreConfig, manipulability_score
from artic.render.noise import SensorNoiseConfig
from artic.render.scan import FusionConfig, ScanViewConfig, fuse_views, view_poses
from artic.sim.cip_envs import CipEnv
from artic.sim.cip_tasks import CipTaskConfig, get_cip_task
from artic.sim.gripper import GripperConfig
from artic.sim.robot import N_JOINTS, TOOL_LINK, IKSettings, Robot, point_jacobian, solve_ik

F64 = NDArray[np.float64]
HeadSetting = Literal["head", "safety", "mv", "cip"]
"""The settings of section 7.3 that start at a grasp (E2E starts at home, no head)."""
IKFunction = Callable[[F64, F64], F64 | None]
#: where every artic object's front (and its handles) faces, in the object's frame
FRONT = np.array([-1.0, 0.0, 0.0])
"""(target world tool pose (4, 4), seed (7,)) -> a joint configuration (7,) or None."""

_SCAN_CAMERA = CameraIntrinsics(fx=300, fy=300, cx=159.5, cy=119.5, width=320, height=240)
_MIN_PART_POINTS = 10


class PartScanConfig(Strict):
    """How the part is observed (Algorithm 3, line 1): a fused scan of the closed object."""

    part: str = Field("handle_0", description="link whose points are kept (the manipulated part)")
    camera: CameraIntrinsics = Field(_SCAN_CAMERA, description="depth camera of each view")
    views: ScanViewConfig = Field(
        ScanViewConfig(distance_m=0.8), description="where the views stand (object frame)"
    )
    noise: SensorNoiseConfig = Field(
        default_factory=SensorNoiseConfig, description="the depth sensor model"
    )
    voxel_m: float = Field(0.004, gt=0, description="fusion voxel grid spacing, m")
    normal_radius_m: float = Field(0.01, gt=0, description="neighbourhood radius of a normal, m")
    normal_neighbours: int = Field(30, ge=3, description="most neighbours of a normal")


class GraspCandidatesConfig(Strict):
    """The grasp candidates G and their filters (constants ours unless marked)."""

    scan: PartScanConfig = Field(default_factory=PartScanConfig, description="observe_scene")
    max_approach_deg: float = Field(
        30.0, gt=0, lt=90, description="largest angle between the approach and -n, deg"
    )
    tilt_deg: float = Field(
        15.0, ge=0, lt=90, description="approach turned about the bar axis by up to this, deg"
    )
    attempts: int = Field(50, ge=1, description="draws per wanted grasp before giving up")
    ik_seeds: int = Field(16, ge=1, description="IK seeds per grasp: home, then random")
    distinct_rad: float = Field(
        0.1, gt=0, description="two IK solutions differ if a joint differs by more, rad"
    )
    clearance_m: float = Field(
        0.005, ge=0, description="least distance of the open gripper and arm to the scene, m"
    )
    fingertip_clearance: float = Field(
        0.01, ge=0, description="fingertips this far short of the part's far side, m"
    )
    exploration: float = Field(1.0, ge=0, description="UCB1's exploration constant c")
    score: GraspScoreConfig = Field(default_factory=GraspScoreConfig, description="w P of Eq. 7.1")


# -- observe_scene: the part's cloud ------------------------------------------------------


class PartCloud(NamedTuple):
    """points: (N, 3) float64, m, object frame; normals: (N, 3) unit, outward (toward
    the views that saw them); viewpoints: (K, 3) the scan's camera positions, m."""

    points: F64
    normals: F64
    viewpoints: F64


def orient_normals(normals: F64, points: F64, viewpoints: F64) -> F64:
    """Normals (N, 3) flipped to face the scan's cameras (viewpoints (K, 3)): a seen
    surface faces a camera that saw it, so of n and -n each point keeps the one whose
    cosine with the direction to a camera is the largest over both signs and all views."""
    to_view = viewpoints[None, :, :] - points[:, None, :]
    to_view /= np.linalg.norm(to_view, axis=2, keepdims=True)
    cosine = np.einsum("nd,nkd->nk", normals, to_view)
    flip = cosine.max(axis=1) + cosine.min(axis=1) < 0.0
    return np.where(flip[:, None], -normals, normals)


def estimate_normals(points: F64, radius: float, neighbours: int) -> F64:
    """(N, 3) unit normals of points (N, 3): Open3D's local plane fit over at most
    `neighbours` points within `radius` m (one thread: the same bytes on every machine);
    unoriented."""
    from threadpoolctl import threadpool_limits

    from artic.render.open3d_core import open3d_core

    o3d = open3d_core()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    search = o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=neighbours)
    with threadpool_limits(limits=1, user_api="openmp"):
        cloud.estimate_normals(search)
    normals = np.asarray(cloud.normals, dtype=np.float64)
    return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def part_cloud(
    model: ArticulatedObject, rng: np.random.Generator, cfg: PartScanConfig | None = None
) -> PartCloud:
    """The fused labelled scan (`render.scan.fuse_views`, ray-cast, `cfg.noise` drawn
    from `rng`) of `model` closed (configuration 0), restricted to `cfg.part`'s points,
    in the object's frame, with outward normals (`estimate_normals`, `orient_normals`).
    InputError if the scan holds fewer than 10 points of the part."""
    from artic.render.backend import make_backend

    cfg = cfg or PartScanConfig()
    q = np.zeros(model.dof)
    poses = view_poses(model, q[None], cfg.camera, cfg.views)
    fusion = FusionConfig(voxel_m=cfg.voxel_m, max_points=0)
    with make_backend("raycast", cfg.camera, threads=1) as backend:
        cloud = fuse_views(model, q, poses, backend, cfg.noise, rng, fusion)
    points = cloud.points[cloud.part_id == model.link_index(cfg.part)].astype(np.float64)
    if len(points) < _MIN_PART_POINTS:
        raise InputError(f"part_cloud: {len(points)} points of {cfg.part} in the scan")
    viewpoints = poses[:, :3, 3]
    normals = estimate_normals(points, cfg.normal_radius_m, cfg.normal_neighbours)
    return PartCloud(points, orient_normals(normals, points, viewpoints), viewpoints)


# -- get_grasp_candidates ----------------------------------------------------------------


def bar_axis(points: F64, facing: F64 | None = None) -> F64:
    """(3,) unit principal direction of points (N, 3) (the handle bar's axis), its
    largest component positive. With `facing` (3,), the direction the part's mount
    faces (every artic object's front: -x of its frame): the principal direction across
    it (the points projected onto the plane it is normal to), so a knob about as deep
    as it is long still gets the long side of its face."""
    centred = points - points.mean(axis=0)
    if facing is not None:
        facing = np.asarray(facing, dtype=np.float64) / np.linalg.norm(facing)
        centred = centred - np.outer(centred @ facing, facing)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    return np.asarray(axis if axis[np.argmax(np.abs(axis))] > 0 else -axis, np.float64)


class SampledGrasps(NamedTuple):
    """poses: (n, 4, 4) tool poses in the cloud's frame; source: (n,) int64, the index of
    the point each was sampled at."""

    poses: F64
    source: NDArray[np.int64]


def sample_grasps(
    points: F64,
    normals: F64,
    rng: np.random.Generator,
    n: int = 100,
    bar_thickness: float = PartsConfig().handle_thickness,
    cfg: GraspCandidatesConfig | None = None,
    finger_length: float = GripperConfig().finger_length,
) -> SampledGrasps:
    """n candidate tool poses in the points' frame (module docstring): at a point drawn
    from points (N, 3) with outward normals (N, 3), approach (z) within
    `cfg.max_approach_deg` of -n, fingers (y) across the bar axis, the tool point half
    `bar_thickness` (m) behind the point, or less where the part is shallower along the
    approach than the fingers (`finger_length` m) reach past it with
    `cfg.fingertip_clearance` to spare (a knob). InputError if no point's normal allows
    the approach, or if n grasps are not found in n x `cfg.attempts` draws."""
    cfg = cfg or GraspCandidatesConfig()
    axis = bar_axis(points, FRONT)
    inward = -(normals - np.outer(normals @ axis, axis))
    length = np.linalg.norm(inward, axis=1)
    min_cosine = math.cos(math.radians(cfg.max_approach_deg))
    usable = np.flatnonzero(length >= min_cosine)
    if len(usable) == 0:
        raise InputError(
            f"sample_grasps: no normal within {cfg.max_approach_deg} deg of the plane "
            "across the bar axis"
        )
    tilt = math.radians(cfg.tilt_deg)
    grasps: list[F64] = []
    source: list[int] = []
    for _ in range(n * cfg.attempts):
        if len(grasps) == n:
            break
        i = int(rng.choice(usable))
        into = inward[i] / length[i]
        angle = rng.uniform(-tilt, tilt)
        approach = math.cos(angle) * into + math.sin(angle) * np.cross(axis, into)
        closing = np.cross(approach, axis)
        closing *= (1.0 if rng.random() < 0.5 else -1.0) / np.linalg.norm(closing)
        if -float(approach @ normals[i]) < min_cosine:
            continue
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2] = np.cross(closing, approach), closing, approach
        depth = float(np.max((points - points[i]) @ into))  # the part behind the point
        reach = depth - cfg.fingertip_clearance - finger_length / 2
        pose[:3, 3] = points[i] + max(0.0, min(0.5 * bar_thickness, reach)) * into
        grasps.append(pose)
        source.append(i)
    if len(grasps) < n:
        raise InputError(f"sample_grasps: {len(grasps)} of {n} grasps in {n * cfg.attempts} draws")
    return SampledGrasps(np.stack(grasps), np.array(source, dtype=np.int64))


# -- the filters -------------------------------------------------------------------------


def ik_seeds(home: F64, low: F64, high: F64, rng: np.random.Generator, count: int = 16) -> F64:
    """(count, 7) IK seeds: home (7,), then count - 1 drawn uniformly within the joint
    limits low, high (7,)."""
    drawn = rng.uniform(low, high, size=(count - 1, len(low)))
    return np.vstack([np.asarray(home, dtype=np.float64)[None], drawn])


def reachable_solutions(
    robot: Robot,
    target: F64,
    seeds: F64,
    margin: float,
    distinct: float = 0.1,
    settings: IKSettings = IKSettings(),
) -> F64:
    """(m, 7) the distinct IK solutions of the world tool pose target (4, 4), one IK run
    (`solve_ik`, which checks the reached pose) per row of seeds (S, 7), in seed order;
    kept if every joint is more than `margin` rad inside its limits (B's threshold: a
    start B already flags is no start) and differs from every kept one by more than
    `distinct` rad in some joint. m may be 0."""
    low, high = robot.limits
    kept: list[F64] = []
    for seed in seeds:
        q = solve_ik(robot, target, seed, settings)
        if q is None or np.minimum(q - low, high - q).min() <= margin:
            continue
        if all(np.abs(q - other).max() > distinct for other in kept):
            kept.append(q)
    return np.array(kept, dtype=np.float64).reshape(-1, N_JOINTS)


def in_collision(
    env: CipEnv, q: F64, clearance: float = 0.005, obstacles: tuple[int, ...] | None = None
) -> bool:
    """Whether the arm at q (7,) with the gripper open (kinematic reset of both) comes
    within `clearance` m of the object (or of each body of `obstacles`) or the ground,
    or touches itself: non-adjacent arm links, the gripper and the arm below the flange
    link. The base and link 0 stand on the ground and are not checked against it.
    Leaves the arm at q."""
    client, body, gripper = env.client, env.robot.body, env.gripper
    env.robot.set_state(q)
    gripper.follow()
    gripper.set_opening(env.task.gripper.travel)
    closest = client.getClosestPoints
    links = range(-1, N_JOINTS)
    if any(closest(body, body, 0.0, linkIndexA=i, linkIndexB=j)
           for i in links for j in links if j >= i + 2):  # fmt: skip
        return True
    if any(closest(gripper.body, body, 0.0, linkIndexB=j) for j in range(-1, TOOL_LINK)):
        return True
    objects = (env.object,) if obstacles is None else obstacles
    if any(closest(part, o, clearance) for part in (body, gripper.body) for o in objects):
        return True
    if closest(gripper.body, env.ground, clearance):
        return True
    return any(closest(body, env.ground, clearance, linkIndexA=j) for j in range(1, N_JOINTS))


def holds_handle(env: CipEnv, q: F64, seed: int) -> bool:
    """Whether Gamma closing at q (7,) holds the handle: `env.reset(seed=seed)` at
    start_q q with the grasp, then both fingers' tactile sums > 0 (the contact filter
    of section 7.4). Rebuilds the environment's scene."""
    env.reset(seed=seed, options={"start_q": q, "grasp": True})
    touch = env.touching()
    return bool(touch[:3].sum() > 0.0 and touch[3:].sum() > 0.0)


def tool_jacobian(robot: Robot, q: F64) -> F64:
    """(6, 7) [linear; angular] Jacobian of the tool point at q (7,): that of link 7's
    centre of mass moved to the tool point (v_tool = v_com + w x r). Leaves the arm at q."""
    robot.set_state(q)
    state = robot.client.getLinkState(robot.body, TOOL_LINK, computeForwardKinematics=1)
    rotation = np.reshape(robot.client.getMatrixFromQuaternion(state[5]), (3, 3))
    tool = np.asarray(state[4]) + rotation[:, 2] * robot.cfg.tool_offset
    jac = point_jacobian(robot, TOOL_LINK, np.asarray(state[2]), q)
    r = tool - np.asarray(state[0])
    return np.vstack([jac[:3] - skew(r) @ jac[3:], jac[3:]])


def score_solutions(robot: Robot, solutions: F64, cfg: GraspScoreConfig) -> F64:
    """(m,) w P (optimize_manipulability's score, Eq. 7.1) of solutions (m, 7)."""
    if len(solutions) == 0:
        return np.zeros(0)
    jacobians = np.stack([tool_jacobian(robot, q) for q in solutions])
    low, high = robot.limits
    return manipulability_score(solutions, jacobians, low, high, cfg)


# -- I_c ----------------------------------------------------------------------------------


class FilterCounts(NamedTuple):
    """Grasps left after each filter: sampled, reachable (an IK solution), collision_free
    (a solution clear of the scene), holding (both fingers on the handle)."""

    sampled: int
    reachable: int
    collision_free: int
    holding: int

    def describe(self) -> str:
        return (
            f"{self.sampled} sampled, {self.reachable} reachable, "
            f"{self.collision_free} collision-free, {self.holding} holding the handle"
        )


@dataclass
class InitiationSet:
    """The domain of I_c and its bandit. grasps: (G, 4, 4) tool poses in the object's
    frame; solutions[g]: (m_g, 7) its IK solutions at `object_pose` (4, 4, world) in the
    order found (seed order: the first is naive IK's), scores[g]: (m_g,) their w P;
    bandit: UCB1 over the G grasps (select_grasp / update_success_rate)."""

    task: str
    object_pose: F64
    grasps: F64
    solutions: list[F64]
    scores: list[F64]
    counts: FilterCounts
    bandit: UCB1

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (initiation_set.json)."""
        grasps = [
            {"pose": g.tolist(), "solutions": s.tolist(), "scores": c.tolist()}
            for g, s, c in zip(self.grasps, self.solutions, self.scores, strict=True)
        ]
        return {"task": self.task, "object_pose": self.object_pose.tolist(),
                "counts": self.counts._asdict(), "grasps": grasps,
                "bandit": self.bandit.to_dict()}  # fmt: skip

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1) + "\n"

    @classmethod
    def from_dict(cls, data: Any, where: str = "initiation_set.json") -> InitiationSet:
        """The set of a `to_dict`; malformed data: InputError naming `where` and the field."""
        try:
            record = _InitiationSetFile.model_validate(data)
        except ValidationError as error:
            first = error.errors()[0]
            field = ".".join(str(p) for p in first["loc"]) or "content"
            raise InputError(f"{where}: {field}: {first['msg']}") from None
        for name, pose in [("object_pose", record.object_pose)] + [
            (f"grasps.{g}.pose", grasp.pose) for g, grasp in enumerate(record.grasps)
        ]:
            if not _is_rigid(np.array(pose)):
                raise InputError(f"{where}: {name}: not a rigid transform")
        for g, grasp in enumerate(record.grasps):
            if len(grasp.scores) != len(grasp.solutions):
                raise InputError(
                    f"{where}: grasps.{g}.scores: {len(grasp.scores)} scores for "
                    f"{len(grasp.solutions)} solutions"
                )
        bandit = UCB1.from_dict(record.bandit.model_dump(), where)
        if bandit.n_arms != len(record.grasps):
            raise InputError(
                f"{where}: bandit.pulls: {bandit.n_arms} arms for {len(record.grasps)} grasps"
            )
        return cls(
            task=record.task,
            object_pose=np.array(record.object_pose),
            grasps=np.array([g.pose for g in record.grasps]),
            solutions=[np.array(g.solutions).reshape(-1, N_JOINTS) for g in record.grasps],
            scores=[np.array(g.scores, dtype=np.float64) for g in record.grasps],
            counts=FilterCounts(**record.counts.model_dump()),
            bandit=bandit,
        )

    @classmethod
    def from_json(cls, text: str, where: str = "initiation_set.json") -> InitiationSet:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as error:
            raise InputError(f"{where}: not JSON ({error.msg}, line {error.lineno})") from None
        return cls.from_dict(data, where)


Row4 = Annotated[list[FiniteFloat], Field(min_length=4, max_length=4)]
Matrix4 = Annotated[list[Row4], Field(min_length=4, max_length=4)]
Configuration = Annotated[list[FiniteFloat], Field(min_length=N_JOINTS, max_length=N_JOINTS)]


class _GraspRecord(Strict):
    pose: Matrix4 = Field(description="tool pose in the object's frame")
    solutions: list[Configuration] = Field(min_length=1, description="IK solutions, rad")
    scores: list[FiniteFloat] = Field(description="w P of each solution")


class _CountsRecord(Strict):
    sampled: int = Field(ge=0, description="grasps sampled")
    reachable: int = Field(ge=0, description="with an IK solution")
    collision_free: int = Field(ge=0, description="with a collision-free solution")
    holding: int = Field(ge=0, description="holding the handle")


class _InitiationSetFile(Strict):
    task: str = Field(description="CIP task name")
    object_pose: Matrix4 = Field(description="world object pose of the filtering scene")
    counts: _CountsRecord = Field(description="grasps left after each filter")
    grasps: list[_GraspRecord] = Field(min_length=1, description="the domain of I_c")
    bandit: BanditState = Field(description="UCB1 state (learning/bandits.py)")


def _is_rigid(pose: F64) -> bool:
    rotation = pose[:3, :3]
    return bool(
        np.allclose(pose[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9)
        and np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6)
        and np.linalg.det(rotation) > 0.0
    )


def nominal_task(task: CipTaskConfig) -> CipTaskConfig:
    """`task` with its object standing still at its nominal pose (no jitter): the scene
    where G is filtered, the centre of the poses the episodes draw."""
    still = task.object.model_copy(update={"jitter_xy": 0.0, "jitter_yaw": 0.0})
    return task.model_copy(update={"object": still})


def build_initiation_set(
    task: str | CipTaskConfig,
    rng: np.random.Generator,
    n: int = 100,
    cfg: GraspCandidatesConfig | None = None,
) -> InitiationSet:
    """Algorithm 3, lines 1-3: scan the task's object at its nominal pose
    (`nominal_task`), sample n grasps on its handle, keep those with a collision-free IK
    solution that holds the handle, score the solutions, and start a bandit over what
    is left. `rng` draws the scan's noise, the grasps and the IK seeds. Runs its own
    environment (closed on return). InputError when no grasp is left (with the counts
    of each filter)."""
    cfg = cfg or GraspCandidatesConfig()
    env = CipEnv(nominal_task(get_cip_task(task) if isinstance(task, str) else task))
    try:
        return _filter(env, rng, n, cfg)
    finally:
        env.close()


def _filter(
    env: CipEnv, rng: np.random.Generator, n: int, cfg: GraspCandidatesConfig
) -> InitiationSet:
    scene = 0  # any seed: the object stands at its nominal pose
    pose = env.draw_pose(scene)
    cloud = part_cloud(env.object_model(pose), rng, cfg.scan)
    sampled = sample_grasps(cloud.points, cloud.normals, rng, n, env.parts.handle_thickness, cfg,
                            env.task.gripper.finger_length)  # fmt: skip
    env.reset(seed=scene)
    low, high = env.limits
    seeds = ik_seeds(np.asarray(env.task.robot.start_q), low, high, rng, cfg.ik_seeds)
    margin = env.task.safety.limit_threshold
    reachable = free = 0
    kept: list[tuple[F64, F64]] = []
    for grasp in sampled.poses:
        found = reachable_solutions(env.robot, pose @ grasp, seeds, margin, cfg.distinct_rad)
        reachable += len(found) > 0
        clear = np.array([q for q in found if not in_collision(env, q, cfg.clearance_m)])
        free += len(clear) > 0
        kept.append((grasp, clear.reshape(-1, N_JOINTS)))
    candidates = [(g, s, score_solutions(env.robot, s, cfg.score)) for g, s in kept if len(s)]
    holding = [c for c in candidates if holds_handle(env, c[1][int(np.argmax(c[2]))], scene)]
    counts = FilterCounts(n, reachable, free, len(holding))
    if not holding:
        raise InputError(f"no grasp left after filtering: {counts.describe()}")
    return InitiationSet(
        task=env.task.name,
        object_pose=pose,
        grasps=np.stack([g for g, _, _ in holding]),
        solutions=[s for _, s, _ in holding],
        scores=[c for _, _, c in holding],
        counts=counts,
        bandit=UCB1(len(holding), cfg.exploration),
    )


# -- the head: select_grasp, get_ik_solns, optimize_manipulability -----------------------


class Start(NamedTuple):
    """The head's choice: grasp (its index in the set), solution (the stored solution
    that warm-started the IK, -1 if none reached), target (4, 4) the world tool pose at
    the episode's object pose, q (7,) the start configuration, None if no IK reached."""

    grasp: int
    solution: int
    target: F64
    q: F64 | None


def robot_ik(robot: Robot, margin: float, settings: IKSettings = IKSettings()) -> IKFunction:
    """An `IKFunction` of `robot` (in a query client): `solve_ik`, None also when a
    joint is within `margin` rad of a limit (as `reachable_solutions` keeps them)."""
    low, high = robot.limits

    def solve(target: F64, seed: F64) -> F64 | None:
        q = solve_ik(robot, target, seed, settings)
        if q is None or np.minimum(q - low, high - q).min() <= margin:
            return None
        return q

    return solve


def choose_grasp(
    initiation_set: InitiationSet, setting: HeadSetting, rng: np.random.Generator
) -> int:
    """select_grasp (line 6): UCB1's arm under `cip`, else a grasp drawn uniformly."""
    if setting == "cip":
        return initiation_set.bandit.select()
    return int(rng.integers(len(initiation_set.grasps)))


def solution_order(initiation_set: InitiationSet, grasp: int, setting: HeadSetting) -> list[int]:
    """The grasp's stored solutions in the order the head tries them (line 8): found
    order under `head` and `safety` (naive IK: the first one), best score first under
    `mv` and `cip` (ties: found order)."""
    scores = initiation_set.scores[grasp]
    if setting in ("head", "safety"):
        return list(range(len(scores)))
    return [int(i) for i in np.argsort(-scores, kind="stable")]


def select_start(
    initiation_set: InitiationSet,
    setting: HeadSetting,
    pose: F64,
    rng: np.random.Generator,
    ik: IKFunction,
    grasp: int | None = None,
) -> Start:
    """Lines 6-8 for one episode whose object stands at pose (4, 4): the setting's grasp
    (`choose_grasp`; `grasp` if given), moved with the object, and IK warm-started from
    its stored solutions in the setting's order (`solution_order`) until one reaches."""
    if setting not in ("head", "safety", "mv", "cip"):
        raise InputError(f"setting: {setting!r} is not one of head, safety, mv, cip")
    if grasp is None:
        grasp = choose_grasp(initiation_set, setting, rng)
    target = np.asarray(pose, dtype=np.float64) @ initiation_set.grasps[grasp]
    for k in solution_order(initiation_set, grasp, setting):
        q = ik(target, initiation_set.solutions[grasp][k])
        if q is not None:
            return Start(grasp, k, target, q)
    return Start(grasp, -1, target, None)


def report_outcome(initiation_set: InitiationSet, grasp: int, success: bool) -> None:
    """update_success_rate (line 14): the episode from `grasp` ended in beta_c or not."""
    initiation_set.bandit.update(grasp, 1.0 if success else 0.0)
