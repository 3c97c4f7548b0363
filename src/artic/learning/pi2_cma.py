"""PI^2-CMA: episode-based Path Integral Policy Improvement with Covariance Matrix
Adaptation (Stulp and Sigaud 2012), the DMP policy search of thesis section 5.3.1.

One update, from the search distribution N(theta, Sigma) over parameter vectors (D,):

1. sample K vectors theta_k = theta + eps_k, eps_k ~ N(0, Sigma) (`ask`);
2. roll each out and get its cost S_k (lower is better; the caller's business);
3. probability weights P_k = exp(-h (S_k - min S) / (max S - min S)), normalised to sum
   to 1 (all costs equal: uniform weights);
4. mean update: theta' = sum_k P_k theta_k;
5. covariance matrix adaptation: Sigma' = sum_k P_k eps_k eps_k^T (the weighted
   covariance of the perturbations about the old mean), blended as
   (1 - lr) Sigma + lr Sigma' (lr = 1 is plain PI^2-CMA); optionally only its diagonal
   (as dmpbbo's default, robust when K is much smaller than D);
6. bounds: the eigenvalues of Sigma' relative to the initial covariance Sigma_0, i.e. of
   L0^-1 Sigma' L0^-T with Sigma_0 = L0 L0^T, are clipped to [min_eigenvalue,
   max_eigenvalue]. Relative bounds keep the floor meaningful when the entries of theta
   have different units (DMP weights, goals in rad, tau in s).

Samples of PI^2 with importance sampling of earlier updates are not reused. Pure numpy;
randomness only from the `np.random.Generator` passed to `ask`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.errors import InputError

F64 = NDArray[np.float64]


class PI2CMAConfig(BaseModel):
    """Hyperparameters of PI^2-CMA."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    n_samples: int = Field(10, ge=2, description="rollouts K per update")
    h: float = Field(10.0, gt=0, description="eliteness: larger h, greedier weights")
    covariance_learning_rate: float = Field(
        1.0, gt=0, le=1, description="blend of the new covariance (1: plain PI^2-CMA)"
    )
    min_eigenvalue: float = Field(
        1e-4, gt=0, description="covariance floor, relative to the initial covariance"
    )
    diagonal_only: bool = Field(
        False, description="keep only the diagonal of the new covariance (robust when K << D)"
    )
    max_eigenvalue: float | None = Field(
        None, gt=0, description="covariance ceiling relative to the initial one (null: none)"
    )

    @model_validator(mode="after")
    def _bounds_ordered(self) -> PI2CMAConfig:
        if self.max_eigenvalue is not None and self.max_eigenvalue < self.min_eigenvalue:
            raise ValueError(
                f"max_eigenvalue {self.max_eigenvalue} < min_eigenvalue {self.min_eigenvalue}"
            )
        return self


@dataclass(frozen=True)
class PI2Update:
    """What one `tell` did. weights: (K,) P_k; mean: (D,) the new mean; step: |theta' -
    theta|; cost_min/mean/max over the K rollouts; eigenvalues_rel: (min, max) of the new
    covariance relative to the initial one; update: the number of updates done so far."""

    weights: F64
    mean: F64
    step: float
    cost_min: float
    cost_mean: float
    cost_max: float
    eigenvalues_rel: tuple[float, float]
    update: int


def probability_weights(costs: F64, h: float) -> F64:
    """P: (K,) exp(-h (S - min)/(max - min)), normalised; uniform when all costs are equal."""
    lo, hi = float(costs.min()), float(costs.max())
    if hi - lo <= 0:
        return np.full(costs.shape, 1.0 / costs.shape[0])
    p = np.exp(-h * (costs - lo) / (hi - lo))
    return p / p.sum()


def _as_covariance(mean: F64, sigma0: Any, cov: Any) -> F64:
    d = mean.shape[0]
    if (sigma0 is None) == (cov is None):
        raise InputError("PI2CMA: give exactly one of sigma0 and cov")
    if sigma0 is not None:
        s = np.asarray(sigma0, dtype=np.float64)
        if s.shape not in ((), (d,)):
            raise InputError(f"PI2CMA.sigma0: expected a scalar or shape ({d},), got {s.shape}")
        s = np.broadcast_to(s, (d,))
        if not (np.isfinite(s).all() and (s > 0).all()):
            raise InputError("PI2CMA.sigma0: standard deviations must be positive and finite")
        return np.diag(s**2)
    c = np.array(cov, dtype=np.float64)
    if c.shape != (d, d) or not np.isfinite(c).all() or not np.allclose(c, c.T):
        raise InputError(f"PI2CMA.cov: expected a finite symmetric ({d}, {d}) matrix")
    try:
        np.linalg.cholesky(c)
    except np.linalg.LinAlgError:
        raise InputError("PI2CMA.cov: not positive definite") from None
    return c


class PI2CMA:
    """Ask/tell PI^2-CMA over vectors (D,). `PI2CMA(mean, cfg, sigma0=0.1)` starts from
    N(mean, sigma0^2 I) (sigma0 may be per-dimension (D,)); or pass `cov` (D, D).

    Fitted state: mean_ (D,), cov_ (D, D), cov0_chol_ (D, D) (Cholesky factor of the
    initial covariance, the reference of the eigenvalue bounds), n_updates_.
    """

    def __init__(
        self,
        mean: F64,
        cfg: PI2CMAConfig | None = None,
        *,
        sigma0: float | F64 | None = None,
        cov: F64 | None = None,
    ) -> None:
        self.cfg = cfg or PI2CMAConfig()
        m = np.array(mean, dtype=np.float64)
        if m.ndim != 1 or m.shape[0] < 1 or not np.isfinite(m).all():
            raise InputError(f"PI2CMA.mean: expected a finite vector (D,), got shape {m.shape}")
        self.mean_ = m
        self.cov_ = _as_covariance(m, sigma0, cov)
        self.cov0_chol_: F64 = np.linalg.cholesky(self.cov_).astype(np.float64)
        self.n_updates_ = 0

    @property
    def dim(self) -> int:
        return int(self.mean_.shape[0])

    def ask(self, rng: np.random.Generator) -> F64:
        """(K, D) samples theta + eps, eps ~ N(0, Sigma); K = cfg.n_samples."""
        eps = rng.standard_normal((self.cfg.n_samples, self.dim))
        return self.mean_ + eps @ np.linalg.cholesky(self.cov_).T

    def tell(self, samples: F64, costs: F64) -> PI2Update:
        """Update mean and covariance from samples (K, D) (usually those `ask` gave) and
        their costs (K,), lower is better."""
        x = np.asarray(samples, dtype=np.float64)
        s = np.asarray(costs, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.dim or x.shape[0] < 2:
            raise InputError(f"PI2CMA.tell: samples must be (K >= 2, {self.dim}), got {x.shape}")
        if s.shape != (x.shape[0],):
            raise InputError(f"PI2CMA.tell: costs must be ({x.shape[0]},), got {s.shape}")
        if not (np.isfinite(x).all() and np.isfinite(s).all()):
            raise InputError("PI2CMA.tell: samples and costs must be finite")
        p = probability_weights(s, self.cfg.h)
        eps = x - self.mean_
        new_mean = p @ x
        new_cov = (eps * p[:, None]).T @ eps
        if self.cfg.diagonal_only:
            new_cov = np.diag(np.diag(new_cov))
        lr = self.cfg.covariance_learning_rate
        cov, rel = self._bounded((1 - lr) * self.cov_ + lr * new_cov)
        step = float(np.linalg.norm(new_mean - self.mean_))
        self.mean_, self.cov_ = new_mean, cov
        self.n_updates_ += 1
        return PI2Update(
            p, new_mean.copy(), step, float(s.min()), float(s.mean()), float(s.max()),
            (float(rel.min()), float(rel.max())), self.n_updates_,
        )  # fmt: skip

    def relative_eigenvalues(self) -> F64:
        """(D,) eigenvalues of L0^-1 Sigma L0^-T (1 = the initial covariance's scale)."""
        return np.linalg.eigvalsh(self._whiten(self.cov_)).astype(np.float64)

    def _whiten(self, cov: F64) -> F64:
        from scipy.linalg import solve_triangular

        a = solve_triangular(self.cov0_chol_, cov, lower=True)
        white = solve_triangular(self.cov0_chol_, a.T, lower=True)
        return 0.5 * (white + white.T)

    def _bounded(self, cov: F64) -> tuple[F64, F64]:
        lam, vec = np.linalg.eigh(self._whiten(cov))
        lam = np.clip(lam, self.cfg.min_eigenvalue, self.cfg.max_eigenvalue)
        lo = self.cov0_chol_ @ vec
        out = (lo * lam) @ lo.T
        return 0.5 * (out + out.T), lam

    # -- checkpoints -------------------------------------------------------------------

    def state_dict(self) -> dict[str, F64]:
        """Arrays that restore this optimiser exactly (with its cfg): for `np.savez`."""
        return {
            "mean": self.mean_.copy(),
            "cov": self.cov_.copy(),
            "cov0_chol": self.cov0_chol_.copy(),
            "n_updates": np.array(self.n_updates_, dtype=np.int64),
        }

    @classmethod
    def from_state_dict(cls, state: dict[str, Any], cfg: PI2CMAConfig) -> PI2CMA:
        """Inverse of `state_dict` (bit-exact)."""
        try:
            mean = np.array(state["mean"], dtype=np.float64)
            cov = np.array(state["cov"], dtype=np.float64)
            chol = np.array(state["cov0_chol"], dtype=np.float64)
            n = int(np.asarray(state["n_updates"]))
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"PI2CMA state: missing or malformed field ({err})") from None
        d = mean.shape[0] if mean.ndim == 1 else -1
        if cov.shape != (d, d) or chol.shape != (d, d) or n < 0:
            raise InputError("PI2CMA state: mean (D,), cov and cov0_chol (D, D) expected")
        out = cls(mean, cfg, cov=chol @ chol.T)
        out.cov_, out.cov0_chol_, out.n_updates_ = cov, chol, n
        return out

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-ready state and config (floats round-trip exactly through `json`)."""
        state = {k: v.tolist() for k, v in self.state_dict().items()}
        return state | {"config": self.cfg.model_dump(mode="json")}

    @classmethod
    def from_json_dict(cls, data: dict[str, Any]) -> PI2CMA:
        """Inverse of `to_json_dict`."""
        if "config" not in data:
            raise InputError("PI2CMA state: missing field config")
        return cls.from_state_dict(data, PI2CMAConfig.model_validate(data["config"]))
