"""One trainer for the supervised networks: the Chapter 3 MDN, the Chapter 4 segmenter and
the Chapter 4 graph labelling network.

What the three share lives here, what differs stays with each network:
- `TrainConfig`: the `train:` section every training stage has (epochs, batch size, Adam's
  learning rate, its schedule and weight decay, early-stopping patience, device, threads);
  each network's section extends it with its own fields and defaults.
- `learning_rate` / `set_learning_rate`: the schedule, constant or a cosine decay from `lr`
  to `lr * min_lr_ratio` over the `epochs` budget, set before every step from (epoch,
  step) alone, so it holds no state of its own and a resumed run continues on it.
- `start_training`: the thread count (part of the numerics) and the device.
- `fit`: the loop over epochs. The network supplies `run_epoch(e)` (one pass over its
  training data in the order drawn from (seed, e), then its validation), the trainer
  does early stopping and the best weights (`FitState.end_epoch`), the per-epoch history
  (`seconds` kept as its own column, for timings.csv only), the log line and the
  per-epoch callback.
- `checkpoint` / `restore`: a checkpoint's content (the parts' state dicts and the
  `FitState`), and resuming from it. Reading and writing the file are the stage's (it
  passes `on_epoch` and the loaded checkpoint): this module touches no files and does not
  import torch until a function needs it.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, TypeVar

from pydantic import Field

from artic.artifacts.timings import SECONDS
from artic.config.schemas import Strict

if TYPE_CHECKING:
    import torch

    from artic.learning.fit_state import FitState

log = logging.getLogger("artic")

#: seconds between progress lines within a long phase (an epoch, building training data)
LOG_EVERY_S = 30.0

S = TypeVar("S", bound="FitState")


class TrainConfig(Strict):
    """The `train:` section of a training stage (networks extend it)."""

    epochs: int = Field(gt=0, description="at most; early stopping usually ends sooner")
    batch_size: int = Field(gt=0)
    lr: float = Field(gt=0, description="Adam's learning rate")
    schedule: Literal["constant", "cosine"] = Field(
        "constant", description="constant: lr throughout; cosine: lr -> lr * min_lr_ratio"
    )
    min_lr_ratio: float = Field(0.01, ge=0, le=1, description="cosine's final lr / lr")
    weight_decay: float = Field(0.0, ge=0)
    patience: int = Field(gt=0, description="epochs without a better validation loss")
    device: Literal["auto", "cpu", "cuda"] = "auto"
    threads: int = Field(
        2, ge=1, description="torch threads: part of the numerics (another count, other weights)"
    )


def learning_rate(cfg: TrainConfig, progress: float) -> float:
    """The learning rate after `progress` epochs (fractional: epoch + step/steps)."""
    if cfg.schedule == "constant":
        return cfg.lr
    t = min(max(progress / cfg.epochs, 0.0), 1.0)
    low = cfg.lr * cfg.min_lr_ratio
    return low + 0.5 * (cfg.lr - low) * (1.0 + math.cos(math.pi * t))


def set_learning_rate(optimizer: torch.optim.Optimizer, cfg: TrainConfig, progress: float) -> None:
    """Every parameter group of `optimizer` at `learning_rate(cfg, progress)`."""
    for group in optimizer.param_groups:
        group["lr"] = learning_rate(cfg, progress)


def training_device(name: str) -> torch.device:
    """`train.device` (auto | cpu | cuda) as a torch device; cuda without one is bad input."""
    import torch

    from artic.errors import InputError

    if name == "cuda" and not torch.cuda.is_available():
        raise InputError("train.device: cuda requested but no CUDA device is available")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(name)


def start_training(cfg: TrainConfig) -> torch.device:
    """Set torch's thread count to `cfg.threads` and return the device to train on."""
    import torch

    torch.set_num_threads(cfg.threads)
    return training_device(cfg.device)


class EpochResult(NamedTuple):
    """What one epoch of a network gives the trainer: the validation loss that early
    stopping watches, and the history columns (besides epoch and seconds), in order."""

    val_loss: float
    metrics: dict[str, float]


def fit(
    model: torch.nn.Module,
    state: S,
    epochs: int,
    patience: int,
    run_epoch: Callable[[int], EpochResult],
    on_epoch: Callable[[S], None],
    summary: Callable[[EpochResult], str] = lambda r: f"val loss {r.val_loss:.3f}",
) -> S:
    """Train from `state` until `epochs` epochs are done or early stopping: `run_epoch(e)`
    for e = state.epoch, ...; after each, the best weights are kept (CPU copy), the history
    gets a row {epoch, **metrics, seconds}, a log line (`summary` of the epoch, the best
    so far, the time) and `on_epoch(state)` (state.epoch = epochs done)."""
    while state.epoch < epochs and not state.stopped_early:
        t0 = time.perf_counter()
        result = run_epoch(state.epoch)
        state.end_epoch(result.val_loss, model, patience)
        seconds = time.perf_counter() - t0
        state.history.append({"epoch": state.epoch, **result.metrics, SECONDS: seconds})
        remaining = (
            "early stop" if state.stopped_early else f"{(epochs - state.epoch) * seconds:.0f} s"
        )
        log.info(
            "epoch %d/%d: %s (best %.3f at %d), %.1f s, ETA %s",
            state.epoch, epochs, summary(result), state.best_val, state.best_epoch, seconds,
            remaining,
        )  # fmt: skip
        on_epoch(state)
    return state


#: what a checkpoint holds the state dicts of: modules and optimizers, by name
Parts = Mapping[str, Any]


def checkpoint(parts: Parts, state: FitState) -> dict[str, Any]:
    """A checkpoint's content: each part's state dict under its name, and the state."""
    return {name: part.state_dict() for name, part in parts.items()} | {"state": state.to_dict()}


def restore(parts: Parts, saved: Mapping[str, Any] | None, state_type: type[S]) -> S:
    """Load a checkpoint (`checkpoint`'s content; None: start afresh) into `parts`, in
    their order, and return its state."""
    if saved is None:
        return state_type()
    for name, part in parts.items():
        part.load_state_dict(saved[name])
    return state_type.from_dict(saved["state"])
