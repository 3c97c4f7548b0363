"""Natural policy gradient (Kakade 2002) and DAPG (Rajeswaran et al. 2017), section 5.3.1.

One update from a batch of trajectories of a Gaussian policy:

1. advantages A_t by generalised advantage estimation (GAE(gamma, lambda); lambda = 1 gives
   Monte-Carlo returns minus the baseline) with the value baseline fitted on the previous
   batch, then standardised to zero mean and unit std;
2. the policy gradient g = (1/N) sum_t grad log pi(a_t | s_t) A_t over the N rollout
   steps; DAPG adds the demonstrations' behaviour-cloning term
   w_k (1/N) sum_{(s,a) in D} grad log pi(a | s) with w_k = lambda_0 lambda_1^k (annealed
   over updates k, so learning stays near the demonstrations at first and later
   optimises reward alone; the paper's w also multiplies by max A, which is ~1-3 for
   standardised advantages);
3. the natural direction x = F^-1 g by conjugate gradient, where F v is the Hessian of
   the mean KL(pi_old || pi_theta) over the rollout states times v (+ damping v);
4. the normalised step theta += sqrt(delta / g^T x) x, so the quadratic KL model of the
   step is delta / 2;
5. the baseline is refitted to the batch's discounted returns.

`NPG` holds the policy, the baseline and the update count; `state_dict`/`load_state_dict`
make a run resumable.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import torch
from numpy.typing import NDArray
from pydantic import Field
from torch import nn

from artic.config.schemas import Strict
from artic.learning.rollout import Trajectory
from artic.policies.gaussian_mlp import GaussianMLPPolicy


class NPGConfig(Strict):
    """NPG / DAPG hyper-parameters (defaults as the DAPG paper where it gives them)."""

    step_size: float = Field(0.05, gt=0, description="normalised step size delta (KL budget)")
    gamma: float = Field(0.995, gt=0, le=1, description="discount")
    gae_lambda: float = Field(0.97, ge=0, le=1, description="GAE lambda (1: Monte-Carlo)")
    cg_iters: int = Field(10, gt=0, description="conjugate-gradient steps for F^-1 g")
    cg_damping: float = Field(1e-4, ge=0, description="damping added to F v")
    baseline: Literal["linear", "mlp"] = Field("linear", description="value baseline")
    baseline_reg: float = Field(1e-5, ge=0, description="ridge coefficient, linear baseline")
    baseline_epochs: int = Field(20, gt=0, description="Adam epochs per update, mlp baseline")
    dapg_lambda0: float = Field(0.1, ge=0, description="DAPG demo weight lambda_0 (0: NPG)")
    dapg_lambda1: float = Field(0.95, gt=0, le=1, description="its decay lambda_1 per update")


@dataclass(frozen=True)
class NPGStep:
    """What one update did: the step length alpha, the KL between the old and new
    policy over the rollout states, the demo weight w_k, and the batch's mean return."""

    alpha: float
    kl: float
    demo_weight: float
    mean_return: float


def discounted_returns(rewards: NDArray[np.float64], gamma: float) -> NDArray[np.float64]:
    """G_t = sum_{i >= t} gamma^(i - t) r_i for rewards (T,) -> (T,)."""
    out = np.zeros_like(rewards, dtype=np.float64)
    acc = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        acc = rewards[t] + gamma * acc
        out[t] = acc
    return out


def gae_advantages(
    rewards: NDArray[np.float64], values: NDArray[np.float64], gamma: float, lam: float
) -> NDArray[np.float64]:
    """GAE: rewards (T,), values V(s_t) (T,) with V = 0 after the last step -> (T,)."""
    v_next = np.append(values[1:], 0.0)
    delta = rewards + gamma * v_next - values
    return discounted_returns(delta, gamma * lam)


def _time_feature(n: int) -> NDArray[np.float64]:
    return np.arange(n, dtype=np.float64)[:, None] / 1000.0


class LinearBaseline:
    """V(s, t) = w . [s, s^2, s^3, t, t^2, t^3, 1] (t = step / 1000), fitted by ridge
    regression to discounted returns (the linear baseline of mjrl)."""

    def __init__(self, obs_dim: int, reg: float = 1e-5) -> None:
        self.obs_dim, self.reg = obs_dim, reg
        self.weights_: NDArray[np.float64] | None = None

    @staticmethod
    def features(obs: NDArray[np.float64]) -> NDArray[np.float64]:
        """obs (T, obs_dim) of one trajectory -> (T, 3 obs_dim + 4)."""
        o = np.clip(obs, -10, 10)
        t = _time_feature(len(obs))
        return np.hstack([o, o**2, o**3, t, t**2, t**3, np.ones_like(t)])

    def fit(self, trajectories: Sequence[Trajectory], returns: Sequence[NDArray[Any]]) -> None:
        x = np.vstack([self.features(t.observations) for t in trajectories])
        y = np.concatenate(returns)
        a = x.T @ x + self.reg * np.trace(x.T @ x) / x.shape[1] * np.eye(x.shape[1])
        self.weights_ = np.linalg.solve(a, x.T @ y)

    def predict(self, trajectory: Trajectory) -> NDArray[np.float64]:
        if self.weights_ is None:
            return np.zeros(len(trajectory))
        return np.asarray(self.features(trajectory.observations) @ self.weights_)

    def state_dict(self) -> dict[str, Any]:
        return {"weights": None if self.weights_ is None else self.weights_.tolist()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        w = state["weights"]
        self.weights_ = None if w is None else np.asarray(w, dtype=np.float64)


class MLPBaseline:
    """V(s, t): MLP (64, 64, tanh) on [s, t], trained with Adam on discounted returns
    (targets standardised); minibatch order from a generator seeded per update."""

    def __init__(self, obs_dim: int, epochs: int = 20, seed: int = 0) -> None:
        gen = torch.Generator().manual_seed(seed)
        self.net = nn.Sequential(nn.Linear(obs_dim + 1, 64), nn.Tanh(), nn.Linear(64, 64),
                                 nn.Tanh(), nn.Linear(64, 1))  # fmt: skip
        with torch.no_grad():
            for p in self.net.parameters():
                p.uniform_(-0.1, 0.1, generator=gen)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=1e-3)
        self.epochs, self.seed, self.fits = epochs, seed, 0
        self.scale_ = 0.0  # 0: not fitted yet, predicts 0

    def _inputs(self, obs: NDArray[np.float64]) -> torch.Tensor:
        return torch.as_tensor(np.hstack([obs, _time_feature(len(obs))]), dtype=torch.float32)

    def fit(self, trajectories: Sequence[Trajectory], returns: Sequence[NDArray[Any]]) -> None:
        x = torch.cat([self._inputs(t.observations) for t in trajectories])
        y_np = np.concatenate(returns)
        self.scale_ = float(np.std(y_np) + 1e-8)
        y = torch.as_tensor(y_np / self.scale_, dtype=torch.float32)[:, None]
        gen = torch.Generator().manual_seed(self.seed * 100_003 + self.fits)
        self.fits += 1
        for _ in range(self.epochs):
            order = torch.randperm(len(x), generator=gen)
            for s in range(0, len(x), 64):
                idx = order[s : s + 64]
                loss = ((self.net(x[idx]) - y[idx]) ** 2).mean()
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()

    def predict(self, trajectory: Trajectory) -> NDArray[np.float64]:
        if self.scale_ == 0.0:
            return np.zeros(len(trajectory))
        with torch.no_grad():
            v = self.net(self._inputs(trajectory.observations))[:, 0].double().numpy()
        return np.asarray(v * self.scale_)

    def state_dict(self) -> dict[str, Any]:
        return {"net": self.net.state_dict(), "optimizer": self.optimizer.state_dict(),
                "fits": self.fits, "scale": self.scale_}  # fmt: skip

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.net.load_state_dict(state["net"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.fits, self.scale_ = int(state["fits"]), float(state["scale"])


def conjugate_gradient(
    fvp: Callable[[torch.Tensor], torch.Tensor], b: torch.Tensor, iters: int
) -> torch.Tensor:
    """Approximate x = A^-1 b for a symmetric positive definite A given by `fvp`."""
    x = torch.zeros_like(b)
    r, p = b.clone(), b.clone()
    rr = r @ r
    for _ in range(iters):
        if rr < 1e-20:
            break
        ap = fvp(p)
        step = rr / (p @ ap)
        x += step * p
        r -= step * ap
        rr_new = r @ r
        p = r + (rr_new / rr) * p
        rr = rr_new
    return x


def gaussian_kl(
    mean_old: torch.Tensor, log_std_old: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor
) -> torch.Tensor:
    """Mean over N states of KL(N(mean_old, std_old) || N(mean, std)): means (N, D),
    log-stds (D,) -> scalar."""
    var_old, var = (2 * log_std_old).exp(), (2 * log_std).exp()
    kl = log_std - log_std_old + (var_old + (mean_old - mean) ** 2) / (2 * var) - 0.5
    return kl.sum(-1).mean()


def _add_to_parameters(params: Iterable[nn.Parameter], step: torch.Tensor) -> None:
    """theta += step, written into each parameter's own storage.

    `torch.nn.utils.vector_to_parameters` would instead make every parameter a view into
    one flat vector (at offsets off a 64-byte boundary); MKL's small matrix products give
    alignment-dependent results on AVX-512 CPUs, so a resumed policy (freshly allocated,
    aligned tensors) would drift from the uninterrupted run by an ulp per rollout.
    """
    offset = 0
    with torch.no_grad():
        for p in params:
            n = p.numel()
            p.add_(step[offset : offset + n].view_as(p))
            offset += n
    if offset != step.numel():
        raise ValueError(f"step has {step.numel()} entries, the parameters {offset}")


class NPG:
    """Natural policy gradient for a `GaussianMLPPolicy`; DAPG when `demos` is given and
    `cfg.dapg_lambda0 > 0`. demos: (obs (M, obs_dim), actions (M, act_dim))."""

    def __init__(
        self,
        policy: GaussianMLPPolicy,
        cfg: NPGConfig,
        demos: tuple[torch.Tensor, torch.Tensor] | None = None,
        seed: int = 0,
    ) -> None:
        self.policy, self.cfg, self.demos = policy, cfg, demos
        self.baseline: LinearBaseline | MLPBaseline = (
            LinearBaseline(policy.obs_dim, cfg.baseline_reg)
            if cfg.baseline == "linear"
            else MLPBaseline(policy.obs_dim, cfg.baseline_epochs, seed)
        )
        self.updates = 0

    def demo_weight(self) -> float:
        """w_k = lambda_0 lambda_1^k at update k (0 without demos)."""
        if self.demos is None:
            return 0.0
        return self.cfg.dapg_lambda0 * self.cfg.dapg_lambda1**self.updates

    def _flat_grad(self, scalar: torch.Tensor, create_graph: bool = False) -> torch.Tensor:
        params = [p for p in self.policy.parameters() if p.requires_grad]
        grads = torch.autograd.grad(scalar, params, create_graph=create_graph)
        return torch.cat([g.reshape(-1) for g in grads])

    def update(self, trajectories: Sequence[Trajectory]) -> NPGStep:
        """One NPG/DAPG step on a batch of trajectories of `self.policy` (see module)."""
        cfg, policy = self.cfg, self.policy
        returns = [discounted_returns(t.rewards, cfg.gamma) for t in trajectories]
        adv = np.concatenate([
            gae_advantages(t.rewards, self.baseline.predict(t), cfg.gamma, cfg.gae_lambda)
            for t in trajectories
        ])  # fmt: skip
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
        obs = torch.as_tensor(
            np.vstack([t.observations for t in trajectories]), dtype=torch.float32
        )
        act = torch.as_tensor(np.vstack([t.actions for t in trajectories]), dtype=torch.float32)
        n = len(obs)
        objective = (policy.log_prob(obs, act) * torch.as_tensor(adv, dtype=torch.float32)).sum()
        w = self.demo_weight()
        if w > 0 and self.demos is not None:
            objective = objective + w * policy.log_prob(*self.demos).sum()
        g = self._flat_grad(objective / n).detach()

        with torch.no_grad():
            mean_old, log_std_old = policy.mean(obs), policy.log_std.detach().clone()

        def fvp(v: torch.Tensor) -> torch.Tensor:
            kl = gaussian_kl(mean_old, log_std_old, policy.mean(obs), policy.log_std)
            grad_kl = self._flat_grad(kl, create_graph=True)
            return self._flat_grad(grad_kl @ v).detach() + cfg.cg_damping * v

        x = conjugate_gradient(fvp, g, cfg.cg_iters)
        gx = float(g @ x)
        alpha = math.sqrt(cfg.step_size / gx) if gx > 1e-20 else 0.0
        _add_to_parameters(policy.parameters(), alpha * x)
        policy.clamp_log_std()
        with torch.no_grad():
            kl_new = float(gaussian_kl(mean_old, log_std_old, policy.mean(obs), policy.log_std))
        self.baseline.fit(trajectories, returns)
        self.updates += 1
        mean_return = float(np.mean([t.total_return for t in trajectories]))
        return NPGStep(alpha, kl_new, w, mean_return)

    def state_dict(self) -> dict[str, Any]:
        return {"policy": self.policy.state_dict(), "baseline": self.baseline.state_dict(),
                "updates": self.updates}  # fmt: skip

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.policy.load_state_dict(state["policy"])
        self.baseline.load_state_dict(state["baseline"])
        self.updates = int(state["updates"])
