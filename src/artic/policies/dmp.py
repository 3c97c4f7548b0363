"""Discrete dynamic movement primitives, one per joint (thesis Eq. 2.4-2.7; Schaal 2006,
Ijspeert et al. 2013), fitted by locally weighted regression (Schaal and Atkeson 1998).

For each joint j (all joints share the phase x):

    tau z' = alpha_z (beta_z (g - y) - z) + f(x)          (Eq. 2.4)
    tau y' = z                                             (Eq. 2.5)
    tau x' = -alpha_x x,  x(0) = 1                         (Eq. 2.6)
    f(x)   = x sum_i w_i psi_i(x) / sum_i psi_i(x)         (Eq. 2.7)
    psi_i(x) = exp(-h_i (x - c_i)^2)

Eq. 2.6 is printed in the thesis as `tau x' = alpha_x x`; the decaying canonical system
of Schaal 2006 / Ijspeert et al. 2013 (minus sign) is meant, with solution
x(t) = exp(-alpha_x t / tau). As in Eq. 2.7, the forcing term is not scaled by (g - y0):
moving the goal moves the end point through the spring-damper and leaves f unchanged.

Basis functions are spaced evenly in time over [0, tau]: c_i = exp(-alpha_x i / (N - 1)),
i = 0..N-1; widths follow the spacing, h_i = 1 / (2 (basis_width d_i)^2) with
d_i = c_i - c_{i+1} (the last basis reuses d_{N-2}), so neighbours overlap.

Rollouts (`rollout_dmp`) integrate Eq. 2.4-2.5 with semi-implicit (symplectic) Euler at
`dt / integration_substeps`: z += h z', then y += h z / tau; the phase is the exact
solution of Eq. 2.6. The DMP starts at rest (z = 0) at y0.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.errors import InputError

F64 = NDArray[np.float64]
DMP_JSON = "dmp.json"  # the DMPs of a fit-dmp folder, and each seed's final PI^2-CMA policy


class DMPConfig(BaseModel):
    """Gains and basis of the DMPs (shared by every joint)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    n_basis: int = Field(32, ge=2, description="radial basis functions N per joint")
    alpha_z: float = Field(25.0, gt=0, description="spring-damper gain alpha_z (Eq. 2.4)")
    beta_z: float = Field(
        6.25, gt=0, description="beta_z (Eq. 2.4); omitted or null: alpha_z / 4 (critical)"
    )
    alpha_x: float = Field(4.0, gt=0, description="phase decay alpha_x (Eq. 2.6); x(tau)=e^-a")
    basis_width: float = Field(0.5, gt=0, description="basis std in units of centre spacing")
    regularization: float = Field(1e-10, ge=0, description="ridge term of each LWR fit")
    integration_substeps: int = Field(4, ge=1, description="Euler substeps per rollout dt")

    @model_validator(mode="before")
    @classmethod
    def _critical_damping(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("beta_z") is None:
            alpha_z = data.get("alpha_z", 25.0)
            if isinstance(alpha_z, int | float):
                data = {**data, "beta_z": alpha_z / 4.0}
        return data

    def centres(self) -> F64:
        """c: (N,) basis centres in phase, evenly spaced in time over [0, tau]."""
        return np.exp(-self.alpha_x * np.arange(self.n_basis) / (self.n_basis - 1))

    def widths(self) -> F64:
        """h: (N,) basis widths from the centre spacing."""
        c = self.centres()
        d = c[:-1] - c[1:]
        d = np.append(d, d[-1])
        return 1.0 / (2.0 * (self.basis_width * d) ** 2)

    def basis(self, x: F64) -> F64:
        """psi: (S, N) basis activations at phases x (S,)."""
        return np.exp(-self.widths() * (x[:, None] - self.centres()) ** 2)

    def phase(self, t: F64, tau: float) -> F64:
        """x: (S,) the exact solution of Eq. 2.6 at times t (S,) seconds."""
        return np.exp(-self.alpha_x * t / tau)

    def forcing(self, weights: F64, x: F64) -> F64:
        """f: (S, J) Eq. 2.7 for weights (J, N) at phases x (S,)."""
        psi = self.basis(x)
        return x[:, None] * (psi @ weights.T) / psi.sum(axis=1, keepdims=True)


@dataclass(frozen=True)
class VectorLayout:
    """Where the searched parameters lie in `DMPParams.to_vector()` (length `size`):
    weights row-major (joint, basis), then goals, then tau."""

    n_joints: int
    n_basis: int

    @property
    def weights(self) -> slice:
        return slice(0, self.n_joints * self.n_basis)

    @property
    def goal(self) -> slice:
        n = self.n_joints * self.n_basis
        return slice(n, n + self.n_joints)

    @property
    def tau(self) -> slice:
        n = self.n_joints * (self.n_basis + 1)
        return slice(n, n + 1)

    @property
    def size(self) -> int:
        return self.n_joints * (self.n_basis + 1) + 1

    def mask(self, block: str) -> NDArray[np.bool_]:
        """(size,) bool, True on the entries of `block` ("weights", "goal" or "tau")."""
        if block not in ("weights", "goal", "tau"):
            raise InputError(f"block: expected weights, goal or tau, got {block!r}")
        out = np.zeros(self.size, dtype=bool)
        out[getattr(self, block)] = True
        return out

    def labels(self) -> list[str]:
        """(size,) names: `w[j,i]`, `goal[j]`, `tau`."""
        w = [f"w[{j},{i}]" for j in range(self.n_joints) for i in range(self.n_basis)]
        return [*w, *(f"goal[{j}]" for j in range(self.n_joints)), "tau"]


@dataclass(frozen=True)
class DMPParams:
    """One DMP per joint. weights_: (J, N) forcing weights (rad/s^2 after the tau^2 of
    Eq. 2.4); y0: (J,) start, rad; goal: (J,) g, rad; tau: time constant = movement
    duration, s."""

    weights_: F64
    y0: F64
    goal: F64
    tau: float

    def __post_init__(self) -> None:
        w, y0, g = (np.asarray(a, dtype=np.float64) for a in (self.weights_, self.y0, self.goal))
        if w.ndim != 2 or y0.shape != (w.shape[0],) or g.shape != (w.shape[0],):
            raise InputError(
                f"DMPParams: expected weights (J, N), y0 (J,), goal (J,); got "
                f"{w.shape}, {y0.shape}, {g.shape}"
            )
        if not (np.isfinite(w).all() and np.isfinite(y0).all() and np.isfinite(g).all()):
            raise InputError("DMPParams: weights, y0 and goal must be finite")
        if not (np.isfinite(self.tau) and self.tau > 0):
            raise InputError(f"DMPParams.tau: expected a positive duration, got {self.tau}")
        object.__setattr__(self, "weights_", w)
        object.__setattr__(self, "y0", y0)
        object.__setattr__(self, "goal", g)
        object.__setattr__(self, "tau", float(self.tau))

    @property
    def n_joints(self) -> int:
        return int(self.weights_.shape[0])

    @property
    def n_basis(self) -> int:
        return int(self.weights_.shape[1])

    @property
    def layout(self) -> VectorLayout:
        return VectorLayout(self.n_joints, self.n_basis)

    def to_vector(self) -> F64:
        """(J N + J + 1,) the parameters policy search varies (section 5.3.1: weights,
        goals and speed), laid out as `self.layout` says; y0 is not searched."""
        return np.concatenate([self.weights_.ravel(), self.goal, [self.tau]])

    def from_vector(self, vector: F64, tau_min: float | None = None) -> DMPParams:
        """These params with weights, goals and tau replaced from `vector` (layout of
        `to_vector`). tau_min: clip tau to at least this (for search samples), else a
        non-positive tau raises InputError."""
        lay = self.layout
        v = np.asarray(vector, dtype=np.float64)
        if v.shape != (lay.size,):
            raise InputError(f"vector: expected shape ({lay.size},), got {v.shape}")
        tau = float(v[lay.tau][0])
        if tau_min is not None:
            tau = max(tau, tau_min)
        weights = v[lay.weights].reshape(self.n_joints, self.n_basis).copy()
        return DMPParams(weights, self.y0.copy(), v[lay.goal].copy(), tau)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready dict; floats round-trip exactly through `json`."""
        return {
            "n_joints": self.n_joints,
            "n_basis": self.n_basis,
            "tau": self.tau,
            "y0": self.y0.tolist(),
            "goal": self.goal.tolist(),
            "weights": self.weights_.tolist(),
        }

    @classmethod
    def from_json_dict(cls, data: dict[str, Any]) -> Self:
        """Inverse of `to_json_dict` (extra keys, such as a dmp.json's gains, are ignored)."""
        try:
            params = cls(
                np.array(data["weights"], dtype=np.float64),
                np.array(data["y0"], dtype=np.float64),
                np.array(data["goal"], dtype=np.float64),
                float(data["tau"]),
            )
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"DMP JSON: missing or malformed field ({err})") from None
        for key in ("n_joints", "n_basis"):
            if key in data and data[key] != getattr(params, key):
                raise InputError(f"DMP JSON: {key} = {data[key]} disagrees with the weights")
        return params


@dataclass(frozen=True)
class DMPTrajectory:
    """A rollout: t (S,) s; y (S, J) rad; yd (S, J) rad/s; ydd (S, J) rad/s^2."""

    t: F64
    y: F64
    yd: F64
    ydd: F64


def _check_demo(t: Any, y: Any, index: int) -> tuple[F64, F64]:
    name = f"demo {index}"
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 1:
        y = y[:, None]
    if t.ndim != 1 or y.ndim != 2:
        raise InputError(f"{name}: expected t (T,) and y (T, J), got {t.shape} and {y.shape}")
    if t.shape[0] != y.shape[0]:
        raise InputError(f"{name}: t has {t.shape[0]} samples but y has {y.shape[0]}")
    if t.shape[0] < 2:
        raise InputError(f"{name}: need at least 2 samples, got {t.shape[0]}")
    if not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise InputError(f"{name}: t and y must be finite (found NaN or inf)")
    if not (np.diff(t) > 0).all():
        raise InputError(f"{name}: t must be strictly increasing")
    return t, y


@dataclass(frozen=True)
class DemoTargets:
    """One demonstration mapped to phase. x: (T,) phase; f: (T, J) forcing targets."""

    x: F64
    f: F64
    y0: F64
    goal: F64
    tau: float


def forcing_targets(t: F64, y: F64, cfg: DMPConfig) -> DemoTargets:
    """Map a demo (t (T,) s, y (T, J) rad) to phase with its own duration tau_d, so demos
    of different lengths align by the fraction of the movement done, and solve Eq. 2.4
    for f with z = tau y': f = tau^2 y'' - alpha_z (beta_z (g - y) - tau y'). Velocities
    and accelerations are finite differences (`np.gradient`, second order where T >= 3)."""
    tau = float(t[-1] - t[0])
    if t.shape[0] >= 3:
        yd = np.gradient(y, t, axis=0, edge_order=2)
        ydd = np.gradient(yd, t, axis=0, edge_order=2)
    else:
        yd = np.gradient(y, t, axis=0, edge_order=1)
        ydd = np.zeros_like(y)
    g = y[-1]
    f = tau**2 * ydd - cfg.alpha_z * (cfg.beta_z * (g - y) - tau * yd)
    return DemoTargets(cfg.phase(t - t[0], tau), f, y[0].copy(), g.copy(), tau)


def fit_dmp(t: F64 | list[F64], y: F64 | list[F64], cfg: DMPConfig | None = None) -> DMPParams:
    """Fit one DMP per joint by locally weighted regression (Schaal and Atkeson 1998).

    t: (T,) s, y: (T, J) rad for one demo, or lists of them for several (lengths may
    differ, joint counts may not). Each basis i and joint j gets its own weighted least
    squares fit of f ~ w x with weights psi_i(x), pooled over every sample of every demo:
    w_ij = sum psi_i x f_j / (sum psi_i x^2 + regularization). The DMP's y0, goal and
    tau are the means over demos of their starts, ends and durations.
    """
    cfg = cfg or DMPConfig()
    ts, ys = (t, y) if isinstance(t, list) else ([t], [y])
    if not isinstance(ys, list) or len(ts) != len(ys):
        raise InputError("fit_dmp: pass t and y as arrays, or as lists of equal length")
    if not ts:
        raise InputError("fit_dmp: no demonstrations")
    demos = [
        forcing_targets(*_check_demo(ti, yi, k), cfg)
        for k, (ti, yi) in enumerate(zip(ts, ys, strict=True))
    ]
    n_joints = demos[0].f.shape[1]
    for k, d in enumerate(demos):
        if d.f.shape[1] != n_joints:
            raise InputError(f"demo {k}: has {d.f.shape[1]} joints, demo 0 has {n_joints}")
    x = np.concatenate([d.x for d in demos])
    f = np.concatenate([d.f for d in demos])
    psi = cfg.basis(x)  # (S, N)
    num = (psi * x[:, None]).T @ f  # (N, J)
    den = psi.T @ x**2 + cfg.regularization  # (N,)
    weights = (num / den[:, None]).T
    y0 = np.mean([d.y0 for d in demos], axis=0)
    goal = np.mean([d.goal for d in demos], axis=0)
    return DMPParams(weights, y0, goal, float(np.mean([d.tau for d in demos])))


def rollout_dmp(params: DMPParams, cfg: DMPConfig, dt: float, steps: int) -> DMPTrajectory:
    """Integrate Eq. 2.4-2.6 from rest at y0 for `steps` samples t_k = k dt (see the module
    docstring for the integrator); returns the trajectory at those samples."""
    if params.n_basis != cfg.n_basis:
        raise InputError(f"DMP: params have {params.n_basis} basis functions, cfg {cfg.n_basis}")
    if not (dt > 0 and steps >= 1):
        raise InputError(f"rollout_dmp: need dt > 0 and steps >= 1, got {dt}, {steps}")
    sub = cfg.integration_substeps
    h = dt / sub
    x = cfg.phase(np.arange(steps * sub, dtype=np.float64) * h, params.tau)
    forcing = cfg.forcing(params.weights_, x)  # (steps * sub, J)
    a, b, tau, g = cfg.alpha_z, cfg.beta_z, params.tau, params.goal
    y = params.y0.copy()
    z = np.zeros_like(y)
    out_y = np.empty((steps, params.n_joints))
    out_z = np.empty_like(out_y)
    out_zd = np.empty_like(out_y)
    for k in range(steps * sub):
        zd = (a * (b * (g - y) - z) + forcing[k]) / tau
        if k % sub == 0:
            i = k // sub
            out_y[i], out_z[i], out_zd[i] = y, z, zd
        z = z + h * zd
        y = y + h * z / tau
    t = np.arange(steps, dtype=np.float64) * dt
    return DMPTrajectory(t, out_y, out_z / tau, out_zd / tau)


@dataclass(frozen=True)
class DMPFile:
    """What a fit-dmp `dmp.json` holds: the task, the control period dt (s) the DMPs were
    fitted at, the gains and basis (`cfg`) and the parameters of every joint."""

    task: str
    dt: float
    params: DMPParams
    cfg: DMPConfig

    def to_json_dict(self) -> dict[str, Any]:
        """The dmp.json layout of docs/formats.md (flat; floats round-trip exactly)."""
        out = {"task": self.task, "dt": self.dt}
        return out | self.cfg.model_dump(mode="json") | self.params.to_json_dict()

    @classmethod
    def from_json_dict(cls, data: dict[str, Any]) -> DMPFile:
        """Inverse of `to_json_dict`; unknown keys are ignored."""
        keys = set(DMPConfig.model_fields)
        try:
            cfg = DMPConfig.model_validate({k: v for k, v in data.items() if k in keys})
            task, dt = str(data["task"]), float(data["dt"])
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"dmp.json: missing or malformed field ({err})") from None
        params = DMPParams.from_json_dict(data)
        if params.n_basis != cfg.n_basis:
            raise InputError(f"dmp.json: n_basis {cfg.n_basis} disagrees with the weights")
        if not dt > 0:
            raise InputError(f"dmp.json: dt must be positive, got {dt}")
        return cls(task, dt, params, cfg)


def read_dmp(folder: Path) -> DMPFile:
    """The DMPs of a fit-dmp output folder (checked against its manifest)."""
    from artic.artifacts.formats import read_json
    from artic.artifacts.manifest import read_manifest, verify_file

    manifest = read_manifest(folder, expected_stage="fit-dmp")
    path = verify_file(folder, manifest, DMP_JSON)
    data = read_json(path)
    try:
        return DMPFile.from_json_dict(data)
    except InputError as err:
        raise InputError(f"{path}: {err}") from None
