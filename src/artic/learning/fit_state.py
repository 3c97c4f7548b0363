"""Epoch bookkeeping of supervised training with early stopping, shared by the Chapter 3
MDN, the Chapter 4 segmenter and the Chapter 4 graph network (`trainer.fit` runs it).

`FitState` is everything a resumed run needs (it is saved in each epoch's checkpoint):
epochs done, the best validation loss and its epoch, epochs since the last improvement,
whether training stopped early, per-epoch metrics, and a CPU copy of the best weights.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Self

import torch

#: older checkpoints named the best validation loss after the stage's loss
_LEGACY_KEYS = {"best_val_nll": "best_val", "best_val_loss": "best_val"}


@dataclass
class FitState:
    """Training progress. `best_val`: the lowest validation loss seen (at `best_epoch`,
    counted from 1); `best_weights`: the model's state dict then (CPU tensors)."""

    epoch: int = 0
    best_val: float = math.inf
    best_epoch: int = 0
    bad_epochs: int = 0
    stopped_early: bool = False
    history: list[dict[str, float]] = field(default_factory=list)
    best_weights: dict[str, torch.Tensor] | None = None

    def end_epoch(self, val_loss: float, model: torch.nn.Module, patience: int) -> bool:
        """Count one finished epoch whose validation loss is `val_loss`: keep a copy of
        the weights if it is the best so far, else stop after `patience` epochs in a row
        without improvement. Returns whether this epoch improved."""
        self.epoch += 1
        if val_loss < self.best_val:
            self.best_val, self.best_epoch, self.bad_epochs = val_loss, self.epoch, 0
            self.best_weights = copy.deepcopy({k: t.cpu() for k, t in model.state_dict().items()})
            return True
        self.bad_epochs += 1
        self.stopped_early = self.bad_epochs >= patience
        return False

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        return cls(**{_LEGACY_KEYS.get(k, k): v for k, v in data.items()})
