"""`artic fit-dmp` (Algorithm 1, line 6): its config and the reproduction table of the
fitted DMPs against the demos they were fitted to (fit.csv)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, model_validator

from artic.config.schemas import StageConfig, Strict
from artic.policies.dmp import DMPConfig, DMPParams, rollout_dmp

FIT_COLUMNS = ["demo", "file", "joint", "range", "rms", "rms_own"]


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


class DemoLike(Protocol):
    """A demonstration as fit-dmp reads it (`artic.artifacts.demo_dataset.Demo`)."""

    @property
    def index(self) -> int: ...
    @property
    def file(self) -> str: ...
    @property
    def t(self) -> NDArray[np.float64]: ...
    @property
    def q(self) -> NDArray[np.float64]: ...


def reproduction_rows(
    demos: Sequence[DemoLike], params: DMPParams, cfg: DMPConfig, dt: float
) -> list[list[Any]]:
    """fit.csv rows (`FIT_COLUMNS`): demo, file, joint, range, rms, rms_own (rad): the RMS
    error of the DMP `params` rolled out at each demo's time stamps, and that of its
    weights with the demo's own start, goal and duration."""
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


def fit_stats(table: list[dict[str, str]]) -> dict[str, float]:
    """The largest reproduction errors of fit.csv's rows (as read back: strings), in mrad
    and relative to the joint's range (joints that move by more than 1 mrad)."""
    span, rms, rms_own = (
        np.array([float(r[c]) for r in table]) for c in ("range", "rms", "rms_own")
    )
    moving = span > 1e-3
    relative = float((rms[moving] / span[moving]).max()) if moving.any() else 0.0
    return {
        "max RMS (mrad)": round(1000 * float(rms.max()), 2),
        "max RMS own start/goal (mrad)": round(1000 * float(rms_own.max()), 2),
        "max RMS / range (%)": round(100 * relative, 3),
    }
