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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from artic.artifacts.formats import read_npz, write_csv, write_json
from artic.artifacts.manifest import read_manifest, verify_file
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import StageConfig, Strict
from artic.errors import InputError
from artic.policies.dmp import DMPConfig, DMPFile, DMPParams, fit_dmp, rollout_dmp

DMP_JSON = "dmp.json"
FIT_CSV = "fit.csv"
FIT_PNG = "fit.png"
DEMOS_JSON = "demos.json"


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


@dataclass(frozen=True)
class Demo:
    """One successful demonstration: t (T,) s from 0; q (T, J) rad."""

    index: int
    file: str
    t: NDArray[np.float64]
    q: NDArray[np.float64]


@dataclass(frozen=True)
class DemoSet:
    task: str
    control_dt: float
    n_joints: int
    demos: list[Demo]
    n_listed: int


def load_demos(folder: Path, task: str, max_demos: int | None = None) -> DemoSet:
    """The successful demos of a plan-demos folder, checked; InputError names the file."""
    manifest = read_manifest(folder, expected_stage="plan-demos")
    index_path = verify_file(folder, manifest, DEMOS_JSON)
    try:
        info = json.loads(index_path.read_text())
        listed = list(info["demos"])
        found_task, dt, n_joints = str(info["task"]), float(info["control_dt"]), info["n_joints"]
    except (ValueError, KeyError, TypeError) as err:
        raise InputError(f"{index_path}: malformed demos index ({err})") from None
    if found_task != task:
        raise InputError(
            f"demos: {folder} holds demos of task '{found_task}', expected '{task}' "
            f"(task={task}); pass the demos of task {task} or task={found_task}"
        )
    if not (isinstance(n_joints, int) and n_joints > 0 and dt > 0):
        raise InputError(f"{index_path}: n_joints and control_dt must be positive")
    ok = [d for d in listed if d.get("status") == "ok" and d.get("file")]
    if not ok:
        raise InputError(
            f"{index_path}: no successful demos ({len(listed)} listed, none with status ok)"
        )
    demos = [_load_demo(folder, manifest, d, n_joints, dt) for d in ok[:max_demos]]
    return DemoSet(found_task, dt, n_joints, demos, len(listed))


def _load_demo(
    folder: Path, manifest: Any, entry: dict[str, Any], n_joints: int, dt: float
) -> Demo:
    path = verify_file(folder, manifest, str(entry["file"]))
    try:
        data = read_npz(path)
        t, q = data["t"].astype(np.float64), data["q_robot"].astype(np.float64)
    except (OSError, ValueError, KeyError) as err:
        raise InputError(f"{path}: not a demo file with t and q_robot ({err})") from None
    if q.ndim != 2 or q.shape[1] != n_joints:
        raise InputError(f"{path}: q_robot has shape {q.shape}, expected (T, {n_joints}) joints")
    if t.shape != (q.shape[0],) or t.shape[0] < 2:
        raise InputError(f"{path}: t has shape {t.shape}, expected ({q.shape[0]},), T >= 2")
    if not (np.isfinite(t).all() and np.isfinite(q).all()):
        raise InputError(f"{path}: t and q_robot must be finite (found NaN or inf)")
    if not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-9):
        raise InputError(f"{path}: t is not uniform with the control dt {dt} s of {DEMOS_JSON}")
    return Demo(int(entry.get("index", 0)), str(entry["file"]), t - t[0], q)


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


def read_dmp(folder: Path) -> DMPFile:
    """The DMPs of a fit-dmp output folder (checked against its manifest)."""
    manifest = read_manifest(folder, expected_stage="fit-dmp")
    path = verify_file(folder, manifest, DMP_JSON)
    try:
        data = json.loads(path.read_text())
    except ValueError as err:
        raise InputError(f"{path}: not JSON ({err})") from None
    try:
        return DMPFile.from_json_dict(data)
    except InputError as err:
        raise InputError(f"{path}: {err}") from None


STAGE: Stage[FitDmpConfig] = Stage(
    name="fit-dmp",
    conf="fit_dmp",
    schema=FitDmpConfig,
    plan=_plan,
    chunk=fit_chunk,
    finalize=_finalize,
    inputs={"demos": "plan-demos"},
    input_paths=lambda cfg: {"demos": Path(cfg.demos)},
)
