"""Policy search from a bootstrapped or a random policy (Algorithm 1, lines 6-10;
section 5.3.1, Figure 5.2): the config of `artic policy-search` and one run (seed) of it.

Algorithms (`algorithm`, `auto` picks the thesis' choice for the task):
- `pi2cma` (drawer, t-ball): DMP policies (one per joint, `artic.policies.dmp`) tracked
  by a joint-velocity controller with feedback (`artic.control.tracking`); PI^2-CMA
  (`artic.learning.pi2_cma`) searches their weights, goals and duration tau. The initial
  DMP is fit-dmp's (`init=bootstrap`) or a random one (`random_dmp`): `baseline=exploring`
  towards a random reachable tool goal near the object, or `baseline=centred` around
  keeping still.
- `dapg` (microwave): a Gaussian MLP policy (hidden (32, 32), tanh), cloned from the
  demos (`init=bootstrap`, then DAPG with those demos) or PyTorch's default
  initialisation with the output layer scaled by 0.01 (`init=random`, plain NPG).

Update 0 is the initial policy; rollouts of update k of run seed s are drawn from (s, k).
After each update the mean policy (no exploration noise) is evaluated from
`eval_rollouts` fixed start states (`Evaluator`); its return R gives the normalised
return 1 - R / R_idle, R_idle the return of a robot that keeps still from the same
starts. A run touches no files: it returns its learning-curve rows (`CURVE_COLUMNS` +
seconds) and its final policy, takes the checkpoint to resume from (None: start afresh)
and hands each update's checkpoint to the caller's `save`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.learning.npg import NPGConfig
from artic.learning.pi2_cma import PI2CMAConfig
from artic.policies.dmp import DMPConfig
from artic.policies.gaussian_mlp import BCConfig
from artic.sim.tasks import TaskConfig

if TYPE_CHECKING:
    from collections.abc import Sequence

    from artic.learning.rollout import ActionFn, Trajectory
    from artic.policies.dmp import DMPFile, DMPParams
    from artic.policies.gaussian_mlp import GaussianMLPPolicy
    from artic.sim.world import TaskWorld

log = logging.getLogger("artic")

CURVE = "learning_curve.csv"
TIMING = "timings.csv"
CURVE_COLUMNS = ["seed", "update", "rollouts", "mean_return", "normalised_return",
                 "success_rate", "train_return", "touch_rate"]  # fmt: skip
N_JOINTS = 7
Extent3 = Annotated[list[Annotated[float, Field(ge=0)]], Field(min_length=3, max_length=3)]
Rows = list[list[Any]]
Checkpoint = dict[str, Any]


class DMPPolicyConfig(Strict):
    """DMP policies, their exploration and their random initialisation."""

    k_p: float = Field(5.0, ge=0, description="feedback gain of the DMP tracker, 1/s")
    sigma_weights: float = Field(20.0, gt=0, description="initial exploration std of weights")
    sigma_goal: float = Field(0.05, gt=0, description="initial exploration std of goals, rad")
    sigma_tau: float = Field(0.1, gt=0, description="initial exploration std of tau, s")
    tau_min: float = Field(0.2, gt=0, description="tau of samples clipped to at least this, s")
    random_weight_std: float = Field(
        20.0, ge=0, description="std of random-init weights, baseline=centred"
    )
    random_tau: float | None = Field(None, gt=0, description="random-init tau (null: episode)")
    explore_weight_std: float = Field(
        150.0, ge=0, description="std of random-init weights, baseline=exploring"
    )
    explore_half_extent: Extent3 = Field(
        default_factory=lambda: [0.07, 0.1, 0.07],
        description="baseline=exploring: half extents (x, y, z) of the world box around the "
        "object's target point (handle, ball) the tool goal is drawn from, m",
    )
    explore_ik_attempts: int = Field(
        50, gt=0, description="baseline=exploring: tool goals drawn until IK reaches one"
    )
    basis: DMPConfig = Field(default_factory=DMPConfig, description="random-init DMP basis")
    pi2cma: PI2CMAConfig = Field(
        default_factory=PI2CMAConfig, description="PI^2-CMA; n_samples is `rollouts`"
    )


class MLPPolicyConfig(BCConfig):
    """Gaussian MLP policies, behaviour cloning (`bc_*`, `BCConfig`) and NPG / DAPG."""

    hidden: list[int] = Field(default_factory=lambda: [32, 32], description="hidden widths")
    init_log_std: float = Field(-0.5, description="initial log std of every action")
    min_log_std: float = Field(-2.5, description="floor of the log std")
    npg: NPGConfig = Field(default_factory=NPGConfig)


class PolicySearchConfig(StageConfig):
    """The config of `artic policy-search` (conf/policy_search/config.yaml)."""

    task: TaskConfig
    init: Literal["bootstrap", "random"] = Field("bootstrap", description="initial policy")
    baseline: Literal["exploring", "centred"] = Field(
        "exploring",
        description="init=random with pi2cma: exploring (a DMP to a random reachable tool goal "
        "near the object) | centred (a DMP around keeping still)",
    )
    algorithm: Literal["auto", "pi2cma", "dapg"] = Field(
        "auto", description="auto: dapg for microwave, pi2cma otherwise (Figure 5.2)"
    )
    dmp: str = Field(description="a fit-dmp output folder (pi2cma, init=bootstrap)")
    demos: str = Field(description="a plan-demos output folder (dapg, init=bootstrap)")
    seeds: int = Field(5, gt=0, description="independent runs (thesis: 20)")
    updates: int = Field(50, ge=0, description="policy updates per run")
    rollouts: int = Field(20, ge=2, description="rollouts per update")
    eval_rollouts: int = Field(3, gt=0, description="rollouts of the mean policy per update")
    pi2cma_policy: DMPPolicyConfig = Field(default_factory=DMPPolicyConfig)
    mlp_policy: MLPPolicyConfig = Field(default_factory=MLPPolicyConfig)

    @model_validator(mode="before")
    @classmethod
    def _samples_are_rollouts(cls, data: Any) -> Any:
        """PI^2-CMA's samples per update K are `rollouts`: pi2cma.n_samples is set from it."""
        rollouts = data.get("rollouts", 20) if isinstance(data, dict) else None
        policy = data.get("pi2cma_policy", {}) if isinstance(data, dict) else None
        if not (isinstance(rollouts, int) and rollouts >= 2 and isinstance(policy, dict)):
            return data  # the field validators report what is wrong
        pi2 = policy.get("pi2cma", {})
        if not isinstance(pi2, dict):
            return data
        if pi2.get("n_samples", rollouts) != rollouts:
            raise ValueError("pi2cma_policy.pi2cma.n_samples: PI^2-CMA samples `rollouts`")
        pi2cma_policy = {**policy, "pi2cma": {**pi2, "n_samples": rollouts}}
        return {**data, "pi2cma_policy": pi2cma_policy}


def algorithm_of(cfg: PolicySearchConfig) -> Literal["pi2cma", "dapg"]:
    if cfg.algorithm != "auto":
        return cfg.algorithm
    return "dapg" if cfg.task.name == "microwave" else "pi2cma"


def run_seed(base: int, index: int) -> int:
    """The seed of run `index`: from numpy's SeedSequence of (base, index)."""
    return int(np.random.SeedSequence([base, index]).generate_state(1)[0])


def seed_dir(index: int) -> str:
    return f"seeds/seed_{index:03d}"


def load_bootstrap_dmp(folder: Path, task: str) -> DMPFile:
    """The DMPFile of a fit-dmp folder, checked to be of `task` with 7 joints."""
    from artic.policies.dmp import read_dmp

    dmp = read_dmp(folder)
    if dmp.task != task:
        raise InputError(f"dmp: {folder} holds DMPs of task '{dmp.task}', expected '{task}'")
    if dmp.params.n_joints != N_JOINTS:
        raise InputError(
            f"dmp: {folder} has {dmp.params.n_joints} joints, the robot has {N_JOINTS}"
        )
    return dmp


class Evaluator:
    """Evaluates a policy's `ActionFn` from the run's fixed evaluation starts; holds
    R_idle of those starts (the robot keeping still)."""

    def __init__(self, env: Any, seed: int, n: int) -> None:
        from artic.learning.rollout import idle_action, returns_of, rollout_seeds, rollouts

        self.env, self.starts = env, rollout_seeds(seed, 0, n, stream=1)
        self.idle = returns_of(rollouts(env, idle_action(N_JOINTS), self.starts))
        if float(self.idle.mean()) >= 0:
            raise InputError("task.goal: the object starts at the goal; nothing to learn")

    def row(self, index: int, update: int, n_rollouts: int, act: ActionFn,
            train: Sequence[Trajectory], seconds: float) -> list[Any]:  # fmt: skip
        """One learning-curve row (`CURVE_COLUMNS` + seconds) of update `update`, whose
        exploration rollouts were `train` (none at update 0: their columns are nan)."""
        from artic.learning.rollout import normalised_return, returns_of, rollouts, touch_rate

        trajs = rollouts(self.env, act, self.starts)
        r = returns_of(trajs)
        success = float(np.mean([t.success for t in trajs]))
        norm = normalised_return(r, self.idle)
        log.info("seed %d update %d: return %.2f, normalised %.3f, success %.2f (%.2f s)",
                 index, update, float(r.mean()), norm, success, seconds)  # fmt: skip
        explored = [returns_of(train).mean(), touch_rate(train)] if train else [np.nan] * 2
        return [index, update, n_rollouts, float(r.mean()), norm, success,
                *(float(v) for v in explored), seconds]  # fmt: skip


def random_dmp(cfg: PolicySearchConfig, seed: int) -> DMPParams:
    """The random initial DMP of run seed `seed` (`cfg.baseline`), drawn from (seed, 4):
    y0 = the task's robot start configuration, tau = `random_tau` (null: the episode
    duration), and
    - centred: goal = y0, forcing weights i.i.d. N(0, `random_weight_std`^2): a sample
      of the search distribution around the do-nothing DMP;
    - exploring: goal = a joint configuration putting the tool at a random point near the
      object (`exploring_goal`), forcing weights i.i.d. N(0, `explore_weight_std`^2), on
      the scale of the weights fitted to planned demos."""
    from artic.policies.dmp import DMPParams

    p = cfg.pi2cma_policy
    rng = np.random.default_rng([seed, 4])
    start = np.array(cfg.task.robot.start_q, dtype=np.float64)
    tau = p.random_tau or cfg.task.horizon * cfg.task.control_dt
    if cfg.baseline == "centred":
        weights = rng.normal(0.0, p.random_weight_std, (N_JOINTS, p.basis.n_basis))
        return DMPParams(weights, start, start.copy(), tau)
    from artic.sim.world import TaskWorld

    with TaskWorld.create(cfg.task) as world:
        goal = exploring_goal(world, p, rng)
    weights = rng.normal(0.0, p.explore_weight_std, (N_JOINTS, p.basis.n_basis))
    return DMPParams(weights, start, goal, tau)


def target_point(world: TaskWorld) -> np.ndarray:
    """(3,) world position of the object's target point at the task's start: the handle's
    grasp point, or the t-ball's ball centre, m."""
    model = world.kinematic_model()
    pose = model.link_poses(np.asarray(world.cfg.object_start))[world.grasp_target_link]
    return np.asarray(pose @ np.append(world.grasp_point, 1.0), dtype=np.float64)[:3]


def approach_pose(position: np.ndarray) -> np.ndarray:
    """(4, 4) tool pose at `position` (3,) whose approach axis (tool +z) points away from
    the robot's base axis, level, and whose x axis lies in the vertical plane through it."""
    d = np.array([position[0], position[1], 0.0])
    d = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(d, [0.0, 0.0, 1.0])
    pose = np.eye(4)
    pose[:3, :3] = np.stack([np.cross(y, d), y, d], axis=1)
    pose[:3, 3] = position
    return pose


def exploring_goal(world: TaskWorld, p: DMPPolicyConfig, rng: np.random.Generator) -> np.ndarray:
    """(7,) joint goal of the exploring baseline: a tool point drawn uniformly from the
    box of half extents `explore_half_extent` around the object's target point
    (`target_point`), the tool approaching it level and away from the robot
    (`approach_pose`), turned into joints by the world's IK from the start configuration
    (`artic.sim.robot.solve_ik`); a point IK cannot reach is redrawn, up to
    `explore_ik_attempts` times, then the goal is the start configuration (logged)."""
    centre = target_point(world)
    start = np.asarray(world.cfg.robot.start_q, dtype=np.float64)
    half = np.asarray(p.explore_half_extent, dtype=np.float64)
    for _ in range(p.explore_ik_attempts):
        point = centre + rng.uniform(-half, half)
        goal = world.ik(approach_pose(point), start)
        if goal is not None:
            return goal
    log.warning("exploring baseline: no reachable tool goal near %s; goal = start", centre)
    return start.copy()


def pi2cma_search(cfg: PolicySearchConfig, index: int, env: Any, params: DMPParams,
                  dcfg: DMPConfig, state: Checkpoint | None,
                  save: Callable[[Checkpoint], None]) -> tuple[Rows, DMPParams]:  # fmt: skip
    """Run `index` of PI^2-CMA over the DMP `params` (gains and basis `dcfg`): the
    learning-curve rows and the final DMP (of the mean). `state`: a checkpoint to resume
    from (arrays; None: start afresh); `save` gets one after every update."""
    from artic.learning.pi2_cma import PI2CMA
    from artic.learning.rollout import dmp_actor, returns_of, rollout, rollout_seeds

    seed, p, task = run_seed(cfg.seed, index), cfg.pi2cma_policy, cfg.task

    def actor(vector: np.ndarray) -> ActionFn:
        theta = params.from_vector(vector, tau_min=p.tau_min)
        return dmp_actor(theta, dcfg, task.control_dt, task.horizon, p.k_p)

    def checkpoint() -> None:
        save({**search.state_dict(), "rows": np.array(rows, dtype=np.float64)})

    evaluator = Evaluator(env, seed, cfg.eval_rollouts)
    if state is not None:
        search = PI2CMA.from_state_dict(state, p.pi2cma)
        rows = [[*(int(v) for v in r[:3]), *r[3:]] for r in state["rows"].tolist()]
    else:
        lay = params.layout
        sigma = np.where(lay.mask("weights"), p.sigma_weights,
                         np.where(lay.mask("goal"), p.sigma_goal, p.sigma_tau))  # fmt: skip
        search = PI2CMA(params.to_vector(), p.pi2cma, sigma0=sigma)
        rows = [evaluator.row(index, 0, 0, actor(search.mean_), [], 0.0)]
        checkpoint()
    for k in range(len(rows), cfg.updates + 1):
        t0 = time.perf_counter()
        samples = search.ask(np.random.default_rng(rollout_seeds(seed, k, 1, stream=2)))
        starts = rollout_seeds(seed, k, cfg.rollouts)
        trajs = [rollout(env, actor(x), s) for x, s in zip(samples, starts, strict=True)]
        search.tell(samples, -returns_of(trajs))
        seconds = time.perf_counter() - t0
        act = actor(search.mean_)
        rows.append(evaluator.row(index, k, k * cfg.rollouts, act, trajs, seconds))
        checkpoint()
    return rows, params.from_vector(search.mean_, tau_min=p.tau_min)


def dapg_search(cfg: PolicySearchConfig, index: int, env: Any,
                demos: tuple[np.ndarray, np.ndarray] | None, state: Checkpoint | None,
                save: Callable[[Checkpoint], None]) -> tuple[Rows, GaussianMLPPolicy]:  # fmt: skip
    """Run `index` of DAPG from the policy cloned from `demos` (obs (M, obs_dim), actions
    (M, 7)), or of NPG from a random policy (`demos` None): the learning-curve rows and
    the final policy. `state`: a checkpoint to resume from (None: start afresh); `save`
    gets one (tensors and plain data) after every update."""
    import torch

    from artic.artifacts.model_file import plain
    from artic.learning.npg import NPG
    from artic.learning.rollout import gaussian_actor, rollout_seeds, rollouts, torch_generator
    from artic.policies.gaussian_mlp import GaussianMLPPolicy, behaviour_clone

    seed, m = run_seed(cfg.seed, index), cfg.mlp_policy
    obs_dim = int(env.observation_space.shape[0])
    gen = torch.Generator().manual_seed(seed)
    policy = GaussianMLPPolicy(obs_dim, N_JOINTS, tuple(m.hidden), m.init_log_std,
                               m.min_log_std, generator=gen)  # fmt: skip
    pairs = None
    if demos is not None:
        o, a = demos
        if o.shape[1] != obs_dim:
            raise InputError(f"demos: states have {o.shape[1]} entries, the env's {obs_dim}")
        pairs = (torch.as_tensor(o, dtype=torch.float32), torch.as_tensor(a, dtype=torch.float32))
    npg = NPG(policy, m.npg, pairs, seed)
    evaluator = Evaluator(env, seed, cfg.eval_rollouts)
    if state is not None:
        npg.load_state_dict(state["npg"])
        rows = state["rows"]
    else:
        if pairs is not None:
            behaviour_clone(policy, *pairs, m, torch_generator(seed, 0, stream=3))
        rows = [evaluator.row(index, 0, 0, gaussian_actor(policy), [], 0.0)]

    def checkpoint() -> None:
        rows[:] = plain(rows)  # numpy scalars as Python ones, as a resumed run reads them
        save({"npg": npg.state_dict(), "rows": rows})

    checkpoint()
    for k in range(len(rows), cfg.updates + 1):
        t0 = time.perf_counter()
        act = gaussian_actor(policy, torch_generator(seed, k))
        trajs = rollouts(env, act, rollout_seeds(seed, k, cfg.rollouts))
        npg.update(trajs)
        seconds = time.perf_counter() - t0
        row = evaluator.row(index, k, k * cfg.rollouts, gaussian_actor(policy), trajs, seconds)
        rows.append(row)
        checkpoint()
    return rows, policy
