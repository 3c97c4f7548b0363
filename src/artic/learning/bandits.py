"""UCB1 over the grasp candidates G: select_grasp and update_success_rate of
Algorithm 3 (thesis section 7.2.1, "Grasp initiation set I_c"; Auer et al. 2002, the
UCB of Kocsis and Szepesvari 2006).

Arm a's value is its success rate Q_a = s_a / n_a; after every arm has been tried (the
untried ones first, lowest index first), the next arm is argmax_a Q_a + c sqrt(ln t /
n_a), t the total number of pulls, ties to the lowest index. No randomness: the same
outcomes give the same choices. The state is a JSON-able dict (`to_dict` /
`from_dict`), what `initiation_set.json` and the training checkpoints hold.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, ValidationError, model_validator

from artic.config.schemas import Strict
from artic.errors import InputError


class BanditState(Strict):
    """The bandit's counts: pulls n_a and summed rewards s_a (successes) per arm."""

    c: float = Field(1.0, ge=0, description="exploration constant of the UCB1 bonus")
    pulls: list[int] = Field(description="times each arm was pulled")
    rewards: list[float] = Field(description="summed rewards (successes) of each arm")

    @model_validator(mode="after")
    def _consistent(self) -> BanditState:
        if not self.pulls:
            raise ValueError("pulls: the bandit needs at least one arm")
        if len(self.pulls) != len(self.rewards):
            raise ValueError(
                f"rewards: {len(self.rewards)} values for {len(self.pulls)} arms in pulls"
            )
        for arm, (n, s) in enumerate(zip(self.pulls, self.rewards, strict=True)):
            if n < 0 or not 0.0 <= s <= n:
                raise ValueError(f"rewards[{arm}] {s} outside [0, pulls[{arm}] = {n}]")
        return self


class UCB1:
    """UCB1 over `n_arms` arms with rewards in [0, 1] (1: the CIP reached beta_c)."""

    def __init__(self, n_arms: int, c: float = 1.0) -> None:
        if n_arms < 1:
            raise InputError(f"UCB1: no arm to choose from (got {n_arms} grasp candidates)")
        self.c = float(c)
        self.pulls = np.zeros(n_arms, dtype=np.int64)
        self.rewards = np.zeros(n_arms, dtype=np.float64)

    @property
    def n_arms(self) -> int:
        return len(self.pulls)

    @property
    def total(self) -> int:
        """t: the pulls so far."""
        return int(self.pulls.sum())

    def success_rates(self) -> NDArray[np.float64]:
        """Q (n_arms,): each arm's success rate, 0 for an untried arm (Algorithm 3, line 3:
        I_c(g) <- 0)."""
        return np.divide(self.rewards, self.pulls, out=np.zeros(self.n_arms), where=self.pulls > 0)

    def upper_bounds(self) -> NDArray[np.float64]:
        """Q + c sqrt(ln t / n) (n_arms,), +inf for an untried arm."""
        bounds = np.full(self.n_arms, np.inf)
        tried = self.pulls > 0
        log_t = math.log(max(self.total, 1))
        bounds[tried] = self.success_rates()[tried] + self.c * np.sqrt(log_t / self.pulls[tried])
        return bounds

    def select(self) -> int:
        """The arm to pull next: the first untried arm, else the largest upper bound
        (ties to the lowest index)."""
        return int(np.argmax(self.upper_bounds()))

    def update(self, arm: int, reward: float) -> None:
        """Record the outcome of pulling `arm`: reward in [0, 1]."""
        if not 0 <= arm < self.n_arms:
            raise ValueError(f"arm {arm} outside 0..{self.n_arms - 1}")
        if not 0.0 <= reward <= 1.0:
            raise ValueError(f"reward {reward} outside [0, 1]")
        self.pulls[arm] += 1
        self.rewards[arm] += reward

    def to_dict(self) -> dict[str, Any]:
        """The state as plain JSON types."""
        return BanditState(
            c=self.c, pulls=self.pulls.tolist(), rewards=self.rewards.tolist()
        ).model_dump()

    @classmethod
    def from_dict(cls, data: Any, where: str = "bandit state") -> UCB1:
        """The bandit of a `to_dict` state; malformed state: InputError naming `where`
        (e.g. the initiation_set.json file) and the field."""
        try:
            state = BanditState.model_validate(data)
        except ValidationError as error:
            first = error.errors()[0]
            field = ".".join(str(p) for p in first["loc"]) or "state"
            raise InputError(f"{where}: {field}: {first['msg']}") from None
        bandit = cls(len(state.pulls), state.c)
        bandit.pulls[:] = state.pulls
        bandit.rewards[:] = state.rewards
        return bandit
