"""`artic fit-dmp`: DMPs fitted to motion-planned demonstrations (Algorithm 1, line 6).

Reads a plan-demos output folder (`demos.json` + `demo_*.npz`), fits one DMP per robot
joint by locally weighted regression over the successful demos (thesis section 5.2.1,
Eq. 2.4-2.7; `artic.policies.dmp.fit_dmp`), and writes:

- `dmp.json`: task, control dt, gains, basis and parameters (docs/formats.md, Chapter 5);
- `fit.csv`: per demo and joint (rad), the demo's range, the RMS reproduction error of
  the written DMP rolled out at the demo's time stamps (`rms`), and that of the fitted
  weights with the demo's own start, goal and duration (`rms_own`). With one demo the
  two agree and measure the fit alone; with several, `rms_own` also shows how far a
  demo's amplitude is from the pooled forcing (Eq. 2.7 does not scale f with g - y0);
- `fit.png` (if `plot`): each joint's demos and the DMP rollout.

One chunk (the fit is milliseconds); no sharding.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, model_validator

from artic.artifacts.formats import write_csv, write_json
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.planning.demo_files import Demo, DemoSet, load_demos
from artic.policies.dmp import DMP_JSON, DMPConfig, DMPFile, DMPParams, fit_dmp, rollout_dmp

FIT_CSV = "fit.csv"
FIT_PNG = "fit.png"


class TaskRef(Strict):
    """The task config group (`conf/common/task`); fit-dmp needs only its name."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str = Field(description="task name: drawer, microwave, tball")

    @model_validator(mode="before")
    @classmethod
    def _from_name(cls, data: Any) -> Any:
        return {"name": data} if isinstance(data, str) else data


class FitDmpConfig(StageConfig):
    task: TaskRef
    demos: str = Field(description="a plan-demos output folder of the task")
    dmp: DMPConfig = Field(default_factory=DMPConfig, description="gains and basis")
    max_demos: int | None = Field(
        None, gt=0, description="fit only the first N successful demos (null: all; thesis: 1)"
    )
    plot: bool = Field(True, description="write fit.png")


def _plan(cfg: FitDmpConfig, inputs: dict[str, Path]) -> Plan:
    demos = load_demos(inputs["demos"], cfg.task.name, cfg.max_demos)
    return Plan([len(demos.demos)], "demos")


def reproduction_rows(
    demos: list[Demo], params: DMPParams, cfg: DMPConfig, dt: float
) -> list[list[Any]]:
    """fit.csv rows: demo, file, joint, range, rms, rms_own (rad)."""
    rows: list[list[Any]] = []
    for demo in demos:
        steps = demo.t.shape[0]
        written = rollout_dmp(params, cfg, dt, steps).y
        own_params = DMPParams(params.weights_, demo.q[0], demo.q[-1], float(demo.t[-1]))
        own = rollout_dmp(own_params, cfg, dt, steps).y
        rms = np.sqrt(((written - demo.q) ** 2).mean(axis=0))
        rms_own = np.sqrt(((own - demo.q) ** 2).mean(axis=0))
        span = np.ptp(demo.q, axis=0)
        for j in range(demo.q.shape[1]):
            rows.append([demo.index, demo.file, j, span[j], rms[j], rms_own[j]])
    return rows


def fit_chunk(cfg: FitDmpConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Fit the DMPs; writes dmp.json, fit.csv (and fit.png) into tmp."""
    demos = load_demos(inputs["demos"], cfg.task.name, cfg.max_demos)
    params = fit_dmp([d.t for d in demos.demos], [d.q for d in demos.demos], cfg.dmp)
    record = DMPFile(cfg.task.name, demos.control_dt, params, cfg.dmp).to_json_dict()
    record["demos_used"] = [d.file for d in demos.demos]
    write_json(tmp / DMP_JSON, record)
    rows = reproduction_rows(demos.demos, params, cfg.dmp, demos.control_dt)
    write_csv(tmp / FIT_CSV, ["demo", "file", "joint", "range", "rms", "rms_own"], rows)
    if cfg.plot:
        _plot(tmp / FIT_PNG, demos, params, cfg.dmp)
    return len(demos.demos)


def _plot(path: Path, demos: DemoSet, params: DMPParams, cfg: DMPConfig) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    longest = max(d.t.shape[0] for d in demos.demos)
    traj = rollout_dmp(params, cfg, demos.control_dt, longest)
    cols = min(4, demos.n_joints)
    rows = -(-demos.n_joints // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False)
    for j, ax in enumerate(axes.ravel()):
        if j >= demos.n_joints:
            ax.axis("off")
            continue
        for k, d in enumerate(demos.demos):
            ax.plot(d.t, d.q[:, j], color="0.6", lw=1, label="demos" if k == 0 else None)
        ax.plot(traj.t, traj.y[:, j], color="C0", lw=1.5, label="DMP")
        ax.set_title(f"joint {j}", fontsize=9)
        ax.set_xlabel("t (s)", fontsize=8)
        ax.set_ylabel("q (rad)", fontsize=8)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"{demos.task}: DMPs ({cfg.n_basis} basis functions) vs demos", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)


def _finalize(
    cfg: FitDmpConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = json.loads((work / DMP_JSON).read_text())
    with (work / FIT_CSV).open(newline="") as f:
        table = list(csv.DictReader(f))
    span, rms, rms_own = (
        np.array([float(r[c]) for r in table]) for c in ("range", "rms", "rms_own")
    )
    moving = span > 1e-3
    relative = float((rms[moving] / span[moving]).max()) if moving.any() else 0.0
    return {
        "task": cfg.task.name,
        "demos used": len(info["demos_used"]),
        "basis functions": cfg.dmp.n_basis,
        "tau (s)": round(float(info["tau"]), 4),
        "max RMS (mrad)": round(1000 * float(rms.max()), 2),
        "max RMS own start/goal (mrad)": round(1000 * float(rms_own.max()), 2),
        "max RMS / range (%)": round(100 * relative, 3),
    }


STAGE: Stage[FitDmpConfig] = Stage(
    name="fit-dmp",
    help=(
        "Dynamic movement primitives fitted to demonstrations by LWR (Eq. 2.4-2.7).\n\n"
        "Example: artic fit-dmp demos=artifacts/demos/drawer"
    ),
    task_option=True,
    conf="fit_dmp",
    schema=FitDmpConfig,
    plan=_plan,
    chunk=fit_chunk,
    finalize=_finalize,
    inputs={"demos": "plan-demos"},
    input_paths=lambda cfg: {"demos": Path(cfg.demos)},
)
