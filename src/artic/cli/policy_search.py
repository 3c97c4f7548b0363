"""`artic policy-search`: policy search from a bootstrapped or a random policy
(Algorithm 1, lines 6-10; section 5.3.1, Figure 5.2). The config and the search loops
are `artic.learning.search`; this stage reads the inputs, keeps the checkpoints and
writes the outputs.

Each seed is one chunk (shardable, resumable); inside a chunk, the search state is
checkpointed after every update in the work area, so Ctrl-C and the same command again
continue from the last finished update (DAPG's `state.pt` and `policy.pt` hold tensors
and plain data only, read with `weights_only=True`; a corrupt one is an InputError naming
it).

Outputs: `learning_curve.csv` (seed, update, rollouts (done so far), mean_return and
normalised_return and success_rate (of the mean policy), train_return (mean over the
update's exploration rollouts; nan at update 0)), `timings.csv` (seed, update, seconds:
wall time of the update's rollouts and step, kept apart so the curve is reproducible
byte for byte), `seeds/seed_NNN/` with the final policy (`dmp.json` in fit-dmp's
format, or `policy.pt`), and `summary.json`.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from artic.artifacts.formats import read_npz, write_csv, write_json
from artic.cli.stage_runner import Plan, Stage, available_cpus
from artic.learning.search import (
    CURVE,
    CURVE_COLUMNS,
    TIMING,
    PolicySearchConfig,
    algorithm_of,
    load_bootstrap_dmp,
    seed_dir,
)
from artic.learning.search import Evaluator as _Evaluator  # noqa: F401  (tests patch its row)
from artic.planning.demo_files import load_demo_pairs


def _input_paths(cfg: PolicySearchConfig) -> dict[str, Path]:
    if cfg.init == "random":
        return {}
    return {"dmp": Path(cfg.dmp)} if algorithm_of(cfg) == "pi2cma" else {"demos": Path(cfg.demos)}


def _plan(cfg: PolicySearchConfig, inputs: dict[str, Path]) -> Plan:
    if "dmp" in inputs:
        load_bootstrap_dmp(inputs["dmp"], cfg.task.name)
    if "demos" in inputs:
        load_demo_pairs(inputs["demos"], cfg.task.name, len(cfg.task.goal))
    return Plan([cfg.updates + 1] * cfg.seeds, "updates")


# -- one run (chunk) -------------------------------------------------------------------


def search_chunk(cfg: PolicySearchConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Run seed `chunk`: policy search with per-update checkpoints in the work area;
    writes the seed's curve and final policy into tmp."""
    from artic.artifacts.model_file import load_torch_file, save_torch_file
    from artic.artifacts.workdir import WorkDir
    from artic.learning.search import dapg_search, pi2cma_search, random_dmp, run_seed
    from artic.policies.dmp import DMP_JSON, DMPFile
    from artic.sim.envs import ArticTaskEnv

    resume = WorkDir(Path(cfg.out)).resume_dir(f"seed_{chunk:03d}")
    out = tmp / seed_dir(chunk)
    out.mkdir(parents=True)
    task = cfg.task
    env = ArticTaskEnv(task, seed=None)
    try:
        if algorithm_of(cfg) == "pi2cma":
            if "dmp" in inputs:
                dmp = load_bootstrap_dmp(inputs["dmp"], task.name)
                params, dcfg = dmp.params, dmp.cfg
            else:
                params, dcfg = random_dmp(cfg, run_seed(cfg.seed, chunk)), cfg.pi2cma_policy.basis
            state_file = resume / "state.npz"
            rows, final = pi2cma_search(cfg, chunk, env, params, dcfg, _load_state(state_file),
                                        lambda state: _save_state(state_file, state))  # fmt: skip
            record = DMPFile(task.name, task.control_dt, final, dcfg).to_json_dict()
            write_json(out / DMP_JSON, record)
        else:
            import torch

            torch.set_num_threads(cfg.runtime.threads or available_cpus())
            demos = None
            if "demos" in inputs:
                demos = load_demo_pairs(inputs["demos"], task.name, len(task.goal))
            path = resume / "state.pt"
            # weights_only; a corrupt state file is an InputError naming it
            state = load_torch_file(path, "checkpoint") if path.is_file() else None
            rows, policy = dapg_search(cfg, chunk, env, demos, state,
                                       lambda state: save_torch_file(path, state))  # fmt: skip
            save_torch_file(out / "policy.pt", {"hparams": policy.hparams,
                            "state_dict": policy.state_dict(), "task": task.name})  # fmt: skip
    finally:
        env.close()
    write_csv(out / "curve.csv", [*CURVE_COLUMNS, "seconds"], rows)
    return len(rows)


def _load_state(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    state = read_npz(path)
    state["n_updates"] = state["n_updates"].reshape(())  # write_npz stores it as (1,)
    return state


def _save_state(path: Path, arrays: dict[str, np.ndarray]) -> None:
    from artic.artifacts.formats import replace_file, write_npz

    tmp = path.with_suffix(".tmp")
    write_npz(tmp, arrays, compress=False)
    replace_file(tmp, path)


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
    help=(
        "Policy search from the bootstrapped policy or from random init (section 5.2.2).\n\n"
        "Example: artic policy-search --task drawer"
    ),
    task_option=True,
    conf="policy_search",
    schema=PolicySearchConfig,
    plan=_plan,
    chunk=search_chunk,
    finalize=_finalize,
    inputs={"dmp": "fit-dmp", "demos": "plan-demos"},
    input_paths=_input_paths,
)
