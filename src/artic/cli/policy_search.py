"""`artic policy-search`: policy search from a bootstrapped or a random policy
(Algorithm 1, lines 6-10; section 5.3.1, Figure 5.2).

Algorithms (`algorithm`, `auto` picks the thesis' choice for the task):
- `pi2cma` (drawer, t-ball): DMP policies (one per joint, `artic.policies.dmp`) tracked
  by a joint-velocity controller with feedback; PI^2-CMA searches their weights, goals
  and duration tau. `init=bootstrap` starts from the fit-dmp output (`dmp=`);
  `init=random` starts from a random DMP: y0 = goal = the task's robot start
  configuration, tau = `pi2cma_policy.random_tau` (null: the episode duration), forcing
  weights i.i.d. N(0, `pi2cma_policy.random_weight_std`^2) drawn from the run's seed.
- `dapg` (microwave): a Gaussian MLP policy (hidden (32, 32), tanh).
  `init=bootstrap` clones the plan-demos demonstrations (`demos=`; pairs (s, a) =
  ([q_robot, q_object], qd_robot)) by maximum likelihood for `mlp_policy.bc_epochs`
  epochs, then runs DAPG with those demos; `init=random` is PyTorch's default
  initialisation drawn from the run's seed with the output layer scaled by 0.01 (mean
  action about 0) and runs plain NPG (the thesis' baseline).

Each seed is one chunk (shardable, resumable); inside a chunk, the search state is
checkpointed after every update in the work area, so Ctrl-C and the same command again
continue from the last finished update (DAPG's `state.pt` and `policy.pt` hold tensors
and plain data only, read with `weights_only=True`; a corrupt one is an InputError naming
it). Update 0 is the initial policy; rollouts of update k of run seed s are drawn from
(s, k). After each update the mean policy (no exploration noise) is evaluated from
`eval_rollouts` fixed start states; its return R gives the normalised return
1 - R / R_idle, where R_idle is the return of a robot that keeps still from the same
starts (0: no better than doing nothing, 1: zero cost).

Outputs: `learning_curve.csv` (seed, update, rollouts (done so far), mean_return and
normalised_return and success_rate (of the mean policy), train_return (mean over the
update's exploration rollouts; nan at update 0)), `timings.csv` (seed, update, seconds:
wall time of the update's rollouts and step, kept apart so the curve is reproducible
byte for byte), `seeds/seed_NNN/` with the final policy (`dmp.json` in fit-dmp's
format, or `policy.pt`), and `summary.json`.
"""

from __future__ import annotations

import csv
import json
import logging
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field

from artic.artifacts.formats import read_npz, write_csv, write_json
from artic.artifacts.manifest import read_manifest, verify_file
from artic.cli.stage_runner import Plan, Stage, available_cpus
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.policies.dmp import DMPConfig
from artic.sim.tasks import TaskConfig

log = logging.getLogger("artic")

CURVE = "learning_curve.csv"
TIMING = "timings.csv"
CURVE_COLUMNS = ["seed", "update", "rollouts", "mean_return", "normalised_return",
                 "success_rate", "train_return"]  # fmt: skip
N_JOINTS = 7


class PI2Settings(Strict):
    """PI^2-CMA (Stulp and Sigaud 2012); samples per update = `rollouts`."""

    h: float = Field(10.0, gt=0, description="eliteness of the probability weights")
    covariance_learning_rate: float = Field(1.0, gt=0, le=1, description="1: plain PI^2-CMA")
    min_eigenvalue: float = Field(1e-3, gt=0, description="covariance floor, relative")
    max_eigenvalue: float | None = Field(None, gt=0, description="covariance ceiling, relative")
    diagonal_only: bool = Field(True, description="diagonal covariance (rollouts << dims)")


class DMPPolicyConfig(Strict):
    """DMP policies, their exploration and their random initialisation."""

    k_p: float = Field(5.0, ge=0, description="feedback gain of the DMP tracker, 1/s")
    sigma_weights: float = Field(20.0, gt=0, description="initial exploration std of weights")
    sigma_goal: float = Field(0.05, gt=0, description="initial exploration std of goals, rad")
    sigma_tau: float = Field(0.1, gt=0, description="initial exploration std of tau, s")
    tau_min: float = Field(0.2, gt=0, description="tau of samples clipped to at least this, s")
    random_weight_std: float = Field(20.0, ge=0, description="std of random-init weights")
    random_tau: float | None = Field(None, gt=0, description="random-init tau (null: episode)")
    basis: DMPConfig = Field(default_factory=DMPConfig, description="random-init DMP basis")
    pi2cma: PI2Settings = Field(default_factory=PI2Settings)


class NPGSettings(Strict):
    """Natural policy gradient / DAPG (artic.learning.npg.NPGConfig)."""

    step_size: float = Field(0.1, gt=0, description="normalised step size delta")
    gamma: float = Field(0.995, gt=0, le=1, description="discount")
    gae_lambda: float = Field(0.97, ge=0, le=1, description="GAE lambda (1: Monte-Carlo)")
    cg_iters: int = Field(10, gt=0)
    cg_damping: float = Field(1e-4, ge=0)
    baseline: Literal["linear", "mlp"] = "linear"
    baseline_reg: float = Field(1e-5, ge=0)
    baseline_epochs: int = Field(20, gt=0)
    dapg_lambda0: float = Field(0.1, ge=0, description="DAPG demo weight lambda_0")
    dapg_lambda1: float = Field(0.95, gt=0, le=1, description="its decay per update")


class MLPPolicyConfig(Strict):
    """Gaussian MLP policies and behaviour cloning."""

    hidden: list[int] = Field(default_factory=lambda: [32, 32], description="hidden widths")
    init_log_std: float = Field(-0.5, description="initial log std of every action")
    min_log_std: float = Field(-2.5, description="floor of the log std")
    bc_epochs: int = Field(10, ge=0, description="behaviour cloning epochs (thesis: 10)")
    bc_batch_size: int = Field(64, gt=0)
    bc_lr: float = Field(1e-3, gt=0)
    npg: NPGSettings = Field(default_factory=NPGSettings)


class PolicySearchConfig(StageConfig):
    task: TaskConfig
    init: Literal["bootstrap", "random"] = Field("bootstrap", description="initial policy")
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


def algorithm_of(cfg: PolicySearchConfig) -> Literal["pi2cma", "dapg"]:
    if cfg.algorithm != "auto":
        return cfg.algorithm
    return "dapg" if cfg.task.name == "microwave" else "pi2cma"


def _input_paths(cfg: PolicySearchConfig) -> dict[str, Path]:
    if cfg.init == "random":
        return {}
    return {"dmp": Path(cfg.dmp)} if algorithm_of(cfg) == "pi2cma" else {"demos": Path(cfg.demos)}


def run_seed(base: int, index: int) -> int:
    """The seed of run `index`: from numpy's SeedSequence of (base, index)."""
    return int(np.random.SeedSequence([base, index]).generate_state(1)[0])


def seed_dir(index: int) -> str:
    return f"seeds/seed_{index:03d}"


# -- inputs ----------------------------------------------------------------------------


def load_bootstrap_dmp(folder: Path, task: str) -> Any:
    """The DMPFile of a fit-dmp folder, checked to be of `task` with 7 joints."""
    from artic.cli.fit_dmp import read_dmp

    dmp = read_dmp(folder)
    if dmp.task != task:
        raise InputError(f"dmp: {folder} holds DMPs of task '{dmp.task}', expected '{task}'")
    if dmp.params.n_joints != N_JOINTS:
        raise InputError(
            f"dmp: {folder} has {dmp.params.n_joints} joints, the robot has {N_JOINTS}"
        )
    return dmp


def load_demo_pairs(folder: Path, task: str, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """(obs (M, 7 + dof), actions (M, 7)) of every successful demo of a plan-demos folder:
    obs = [q_robot, q_object], action = qd_robot."""
    manifest = read_manifest(folder, expected_stage="plan-demos")
    index = verify_file(folder, manifest, "demos.json")
    try:
        info = json.loads(index.read_text())
        found, entries = str(info["task"]), list(info["demos"])
    except (ValueError, KeyError, TypeError) as err:
        raise InputError(f"{index}: malformed demos index ({err})") from None
    if found != task:
        raise InputError(f"demos: {folder} holds demos of task '{found}', expected '{task}'")
    obs, act = [], []
    for entry in entries:
        if entry.get("status") != "ok" or not entry.get("file"):
            continue
        path = verify_file(folder, manifest, str(entry["file"]))
        try:
            data = read_npz(path)
            q, qd, qo = data["q_robot"], data["qd_robot"], data["q_object"]
        except (OSError, ValueError, KeyError) as err:
            raise InputError(
                f"{path}: not a demo with q_robot, qd_robot, q_object ({err})"
            ) from None
        qo = qo.reshape(len(qo), -1)
        if q.ndim != 2 or q.shape[1] != N_JOINTS or qd.shape != q.shape:
            raise InputError(f"{path}: q_robot/qd_robot must be (T, {N_JOINTS}), got {q.shape}")
        if qo.shape != (len(q), dof):
            raise InputError(f"{path}: q_object must be ({len(q)}, {dof}), got {qo.shape}")
        obs.append(np.hstack([q, qo]))
        act.append(qd)
    if not obs:
        raise InputError(f"{index}: no successful demos")
    o, a = np.vstack(obs), np.vstack(act)
    if not (np.isfinite(o).all() and np.isfinite(a).all()):
        raise InputError(f"demos: {folder} has NaN or inf in q_robot, qd_robot or q_object")
    return o, a


def _plan(cfg: PolicySearchConfig, inputs: dict[str, Path]) -> Plan:
    if "dmp" in inputs:
        load_bootstrap_dmp(inputs["dmp"], cfg.task.name)
    if "demos" in inputs:
        load_demo_pairs(inputs["demos"], cfg.task.name, len(cfg.task.goal))
    return Plan([cfg.updates + 1] * cfg.seeds, "updates")


# -- one run (chunk) -------------------------------------------------------------------


def search_chunk(cfg: PolicySearchConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Run seed `chunk`: policy search with per-update checkpoints; writes the seed's
    curve and final policy into tmp."""
    from artic.artifacts.workdir import WorkDir
    from artic.sim.envs import ArticTaskEnv

    resume = WorkDir(Path(cfg.out)).resume_dir(f"seed_{chunk:03d}")
    out = tmp / seed_dir(chunk)
    out.mkdir(parents=True)
    env = ArticTaskEnv(cfg.task, seed=None)
    try:
        runner = _run_pi2cma if algorithm_of(cfg) == "pi2cma" else _run_dapg
        rows = runner(cfg, inputs, chunk, env, resume, out)
    finally:
        env.close()
    write_csv(out / "curve.csv", [*CURVE_COLUMNS, "seconds"], rows)
    return len(rows)


class _Evaluator:
    """Evaluates a policy's `ActionFn` from the run's fixed evaluation starts; holds
    R_idle of those starts (the robot keeping still)."""

    def __init__(self, env: Any, seed: int, n: int) -> None:
        from artic.learning.rollout import idle_action, returns_of, rollout_seeds, rollouts

        self.env, self.starts = env, rollout_seeds(seed, 0, n, stream=1)
        self.idle = returns_of(rollouts(env, idle_action(N_JOINTS), self.starts))
        if float(self.idle.mean()) >= 0:
            raise InputError("task.goal: the object starts at the goal; nothing to learn")

    def row(self, index: int, update: int, n_rollouts: int, act: Any, train: float,
            seconds: float) -> list[Any]:  # fmt: skip
        from artic.learning.rollout import normalised_return, returns_of, rollouts

        trajs = rollouts(self.env, act, self.starts)
        r = returns_of(trajs)
        success = float(np.mean([t.success for t in trajs]))
        norm = normalised_return(r, self.idle)
        log.info("seed %d update %d: return %.2f, normalised %.3f, success %.2f (%.2f s)",
                 index, update, float(r.mean()), norm, success, seconds)  # fmt: skip
        return [index, update, n_rollouts, float(r.mean()), norm, success, train, seconds]


def _save_state(path: Path, arrays: dict[str, np.ndarray], rows: list[list[Any]]) -> None:
    from artic.artifacts.formats import replace_file, write_npz

    tmp = path.with_suffix(".tmp")
    write_npz(tmp, {**arrays, "rows": np.array(rows, dtype=np.float64)}, compress=False)
    replace_file(tmp, path)


def random_dmp(cfg: PolicySearchConfig, seed: int) -> Any:
    """The random initial DMP of the module docstring."""
    from artic.policies.dmp import DMPParams

    p = cfg.pi2cma_policy
    rng = np.random.default_rng([seed, 4])
    start = np.array(cfg.task.robot.start_q, dtype=np.float64)
    weights = rng.normal(0.0, p.random_weight_std, (N_JOINTS, p.basis.n_basis))
    tau = p.random_tau or cfg.task.horizon * cfg.task.control_dt
    return DMPParams(weights, start, start.copy(), tau)


def _run_pi2cma(cfg: PolicySearchConfig, inputs: dict[str, Path], index: int, env: Any,
                resume: Path, out: Path) -> list[list[Any]]:  # fmt: skip
    from artic.learning.pi2_cma import PI2CMA, PI2CMAConfig
    from artic.learning.rollout import dmp_actor, returns_of, rollout_seeds, rollouts
    from artic.policies.dmp import DMPFile

    seed, p, task = run_seed(cfg.seed, index), cfg.pi2cma_policy, cfg.task
    if "dmp" in inputs:
        dmp = load_bootstrap_dmp(inputs["dmp"], task.name)
        params, dcfg = dmp.params, dmp.cfg
    else:
        params, dcfg = random_dmp(cfg, seed), p.basis

    def actor(vector: np.ndarray) -> Any:
        theta = params.from_vector(vector, tau_min=p.tau_min)
        return dmp_actor(theta, dcfg, task.control_dt, task.horizon, p.k_p)

    pi2 = PI2CMAConfig(n_samples=cfg.rollouts, **p.pi2cma.model_dump())
    evaluator = _Evaluator(env, seed, cfg.eval_rollouts)
    state_file = resume / "state.npz"
    if state_file.is_file():
        state = read_npz(state_file)
        state["n_updates"] = state["n_updates"].reshape(())  # write_npz stores it as (1,)
        search = PI2CMA.from_state_dict(state, pi2)
        rows = [[*(int(v) for v in r[:3]), *r[3:]] for r in state["rows"].tolist()]
    else:
        lay = params.layout
        sigma = np.where(lay.mask("weights"), p.sigma_weights,
                         np.where(lay.mask("goal"), p.sigma_goal, p.sigma_tau))  # fmt: skip
        search = PI2CMA(params.to_vector(), pi2, sigma0=sigma)
        rows = [evaluator.row(index, 0, 0, actor(search.mean_), float("nan"), 0.0)]
        _save_state(state_file, search.state_dict(), rows)
    for k in range(len(rows), cfg.updates + 1):
        t0 = time.perf_counter()
        samples = search.ask(np.random.default_rng(rollout_seeds(seed, k, 1, stream=2)))
        starts = rollout_seeds(seed, k, cfg.rollouts)
        returns = np.array([returns_of(rollouts(env, actor(x), [s]))[0]
                            for x, s in zip(samples, starts, strict=True)])  # fmt: skip
        search.tell(samples, -returns)
        seconds = time.perf_counter() - t0
        act = actor(search.mean_)
        rows.append(evaluator.row(index, k, k * cfg.rollouts, act, float(returns.mean()), seconds))
        _save_state(state_file, search.state_dict(), rows)
    final = params.from_vector(search.mean_, tau_min=p.tau_min)
    write_json(out / "dmp.json", DMPFile(task.name, task.control_dt, final, dcfg).to_json_dict())
    return rows


def _run_dapg(cfg: PolicySearchConfig, inputs: dict[str, Path], index: int, env: Any,
              resume: Path, out: Path) -> list[list[Any]]:  # fmt: skip
    import torch

    from artic.artifacts.model_file import load_torch_file, plain, save_torch_file
    from artic.learning.npg import NPG, NPGConfig
    from artic.learning.rollout import gaussian_actor, rollout_seeds, rollouts, torch_generator
    from artic.policies.gaussian_mlp import BCConfig, GaussianMLPPolicy, behaviour_clone

    torch.set_num_threads(cfg.runtime.threads or available_cpus())
    seed, m = run_seed(cfg.seed, index), cfg.mlp_policy
    obs_dim = int(env.observation_space.shape[0])
    gen = torch.Generator().manual_seed(seed)
    policy = GaussianMLPPolicy(obs_dim, N_JOINTS, tuple(m.hidden), m.init_log_std,
                               m.min_log_std, generator=gen)  # fmt: skip
    demos = None
    if "demos" in inputs:
        o, a = load_demo_pairs(inputs["demos"], cfg.task.name, len(cfg.task.goal))
        if o.shape[1] != obs_dim:
            raise InputError(f"demos: states have {o.shape[1]} entries, the env's {obs_dim}")
        demos = (torch.as_tensor(o, dtype=torch.float32), torch.as_tensor(a, dtype=torch.float32))
    npg = NPG(policy, NPGConfig(**m.npg.model_dump()), demos, seed)
    evaluator = _Evaluator(env, seed, cfg.eval_rollouts)
    state_file = resume / "state.pt"
    if state_file.is_file():  # weights_only; a corrupt state file is an InputError naming it
        state = load_torch_file(state_file, "checkpoint")
        npg.load_state_dict(state["npg"])
        rows = state["rows"]
    else:
        if demos is not None:
            bc = BCConfig(m.bc_epochs, m.bc_batch_size, m.bc_lr)
            behaviour_clone(policy, *demos, bc, torch_generator(seed, 0, stream=3))
        rows = [evaluator.row(index, 0, 0, gaussian_actor(policy), float("nan"), 0.0)]

    def checkpoint() -> None:
        rows[:] = plain(rows)  # numpy scalars as Python ones, as a resumed run reads them
        save_torch_file(state_file, {"npg": npg.state_dict(), "rows": rows})

    checkpoint()
    for k in range(len(rows), cfg.updates + 1):
        t0 = time.perf_counter()
        act = gaussian_actor(policy, torch_generator(seed, k))
        step = npg.update(rollouts(env, act, rollout_seeds(seed, k, cfg.rollouts)))
        seconds = time.perf_counter() - t0
        row = evaluator.row(index, k, k * cfg.rollouts, gaussian_actor(policy),
                            step.mean_return, seconds)  # fmt: skip
        rows.append(row)
        checkpoint()
    save_torch_file(out / "policy.pt", {"hparams": policy.hparams,
                    "state_dict": policy.state_dict(), "task": cfg.task.name})  # fmt: skip
    return rows


def _finalize(
    cfg: PolicySearchConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    rows: list[list[str]] = []
    for i in range(cfg.seeds):
        with (work / seed_dir(i) / "curve.csv").open(newline="") as f:
            rows.extend(list(csv.reader(f))[1:])
        (work / seed_dir(i) / "curve.csv").unlink()
    table = np.array([[float(v) for v in r] for r in rows])
    write_csv(work / CURVE, CURVE_COLUMNS, [r[:-1] for r in rows])
    write_csv(work / TIMING, ["seed", "update", "seconds"], [[r[0], r[1], r[-1]] for r in rows])
    last = table[table[:, 1] == cfg.updates]
    first = table[table[:, 1] == 0]
    seconds = table[table[:, 1] > 0, 7]
    summary = {
        "task": cfg.task.name,
        "init": cfg.init,
        "algorithm": algorithm_of(cfg),
        "policy": "dmp" if algorithm_of(cfg) == "pi2cma" else "gaussian_mlp",
        "seeds": cfg.seeds,
        "updates": cfg.updates,
        "rollouts_per_update": cfg.rollouts,
        "eval_rollouts": cfg.eval_rollouts,
        "initial_normalised_return": _mean_sem(first[:, 4]),
        "final_normalised_return": _mean_sem(last[:, 4]),
        "final_success_rate": float(last[:, 5].mean()),
        "normalised_return": "1 - R / R_idle; R: return of the mean policy from fixed starts, "
        "R_idle: return of a robot that keeps still from the same starts",
        "random_init": (
            "DMP: y0 = goal = robot start, weights ~ N(0, random_weight_std^2)"
            if algorithm_of(cfg) == "pi2cma"
            else "MLP: PyTorch default init, output layer x0.01 (mean action ~ 0)"
        ),
        "inputs": {k: str(v) for k, v in inputs.items()},
        "final_policies": [
            f"{seed_dir(i)}/{'dmp.json' if algorithm_of(cfg) == 'pi2cma' else 'policy.pt'}"
            for i in range(cfg.seeds)
        ],
    }
    write_json(work / "summary.json", summary)
    return {
        "task": cfg.task.name,
        "init": cfg.init,
        "algorithm": algorithm_of(cfg),
        "seeds": cfg.seeds,
        "final normalised return": round(float(last[:, 4].mean()), 4),
        "final success rate": round(float(last[:, 5].mean()), 3),
        "s per update": round(float(seconds.mean()), 3) if len(seconds) else 0.0,
    }


def _mean_sem(x: np.ndarray) -> dict[str, float]:
    sem = float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else 0.0
    return {"mean": float(x.mean()), "sem": sem}


STAGE: Stage[PolicySearchConfig] = Stage(
    name="policy-search",
    conf="policy_search",
    schema=PolicySearchConfig,
    plan=_plan,
    chunk=search_chunk,
    finalize=_finalize,
    inputs={"dmp": "fit-dmp", "demos": "plan-demos"},
    input_paths=_input_paths,
)
