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
normalised_return and success_rate (of the mean policy), train_return and touch_rate
(mean return over the update's exploration rollouts, and the share of them in which the
robot touched the object: `info["touched"]` of `artic.sim.envs`; nan at update 0)),
`timings.csv` (seed, update, seconds: wall time of the update's rollouts and step, kept
apart so the curve is reproducible byte for byte), `seeds/seed_NNN/` with the final
policy (`dmp.json` in fit-dmp's format, or `policy.pt`), and `summary.json`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from artic.artifacts.chunk_parts import take_csv_rows
from artic.artifacts.demo_dataset import load_demo_pairs
from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.workers import available_cpus
from artic.cli.stage_runner import Plan, Stage
from artic.learning.search import (
    CURVE,
    CURVE_COLUMNS,
    TIMING,
    PolicySearchConfig,
    algorithm_of,
    load_bootstrap_dmp,
    seed_dir,
)
from artic.learning.search_output import run_summary


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
    from artic.artifacts.resume import load_state, save_state
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
            rows, final = pi2cma_search(cfg, chunk, env, params, dcfg, load_state(state_file),
                                        lambda state: save_state(state_file, state))  # fmt: skip
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


def _finalize(
    cfg: PolicySearchConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    rows = take_csv_rows(work / seed_dir(i) / "curve.csv" for i in range(cfg.seeds))
    write_csv(work / CURVE, CURVE_COLUMNS, [r[:-1] for r in rows])
    write_csv(work / TIMING, ["seed", "update", "seconds"], [[r[0], r[1], r[-1]] for r in rows])
    table = np.array([[float(v) for v in r] for r in rows])
    summary, stats = run_summary(cfg, {k: str(v) for k, v in inputs.items()}, table)
    write_json(work / "summary.json", summary)
    return stats


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
