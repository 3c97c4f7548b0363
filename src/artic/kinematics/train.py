"""Training of the per-category MDN (Eq. 3.2): Adam on the negative log-likelihood,
validation on withheld objects after every epoch, early stopping on validation NLL.

Learning rate: `train.schedule`, constant or a cosine decay from `lr` to `lr *
min_lr_ratio` over the `epochs` budget, set before every step from (epoch, step) alone
(`learning.trainer.learning_rate`), so the schedule holds no state of its own.

Resumable and reproducible: the order of epoch e's batches and its augmentation come
from generators seeded by (seed, e), so a run resumed from the checkpoint of epoch e
continues exactly as the uninterrupted run would. Saving checkpoints is the caller's
(`on_epoch`); this module touches no files.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
import torch

from artic.kinematics.config import MdnTrainConfig
from artic.kinematics.data import DepthSplit
from artic.kinematics.mdn import KinematicsMDN, mdn_nll
from artic.kinematics.preprocess import InputPipeline, augment
from artic.kinematics.targets import TargetCodec
from artic.learning import trainer
from artic.learning.fit_state import FitState

log = logging.getLogger("artic")


def fit(
    model: KinematicsMDN,
    optimizer: torch.optim.Optimizer,
    train: DepthSplit,
    val: DepthSplit,
    codec: TargetCodec,
    inputs: InputPipeline,
    cfg: MdnTrainConfig,
    seed: int,
    state: FitState,
    device: torch.device,
    on_epoch: Callable[[FitState], None],
) -> FitState:
    """Train from `state` until `cfg.epochs` or early stopping (`learning.trainer.fit`);
    `on_epoch(state)` after each epoch (state.epoch = epochs done)."""
    model.to(device)
    if cfg.channels_last:
        model.to(memory_format=torch.channels_last)  # type: ignore[call-overload]
    y_train = torch.from_numpy(codec.encode(train.labels))

    def run_epoch(epoch: int) -> trainer.EpochResult:
        train_nll = _train_epoch(model, optimizer, train, y_train, inputs, cfg, seed, epoch, device)
        val_nll = evaluate_nll(model, val, codec, inputs, cfg.batch_size, device, cfg.channels_last)
        lr = float(optimizer.param_groups[0]["lr"])
        return trainer.EpochResult(val_nll, {"train_nll": train_nll, "val_nll": val_nll, "lr": lr})

    def summary(r: trainer.EpochResult) -> str:
        return f"train NLL {r.metrics['train_nll']:.3f}, val NLL {r.val_loss:.3f}"

    return trainer.fit(model, state, cfg.epochs, cfg.patience, run_epoch, on_epoch, summary)


def _train_epoch(
    model: KinematicsMDN,
    optimizer: torch.optim.Optimizer,
    data: DepthSplit,
    targets: torch.Tensor,
    inputs: InputPipeline,
    cfg: MdnTrainConfig,
    seed: int,
    epoch: int,
    device: torch.device,
) -> float:
    model.train()
    order = np.random.default_rng([seed, epoch]).permutation(len(data))
    generator = torch.Generator(device=device).manual_seed(seed * 100_003 + epoch)
    total, seen, last_log = 0.0, 0, time.perf_counter()
    for start in range(0, len(order), cfg.batch_size):
        index = np.sort(order[start : start + cfg.batch_size])
        if len(index) < 2:
            continue  # BatchNorm needs two images per batch in training mode
        trainer.set_learning_rate(optimizer, cfg, epoch + start / len(order))
        x = inputs(data.depth_m(index)).to(device, cfg.channels_last)
        x = augment(x, cfg.augment_dropout, generator)
        loss = mdn_nll(model(*x), targets[index].to(device))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        total += loss.item() * len(index)
        seen += len(index)
        if time.perf_counter() - last_log > trainer.LOG_EVERY_S:
            log.info("  epoch %d: %d/%d images, NLL %.3f", epoch + 1, seen, len(data), total / seen)
            last_log = time.perf_counter()
    return total / max(seen, 1)


@torch.no_grad()
def evaluate_nll(
    model: KinematicsMDN,
    data: DepthSplit,
    codec: TargetCodec,
    inputs: InputPipeline,
    batch_size: int,
    device: torch.device,
    channels_last: bool = True,
) -> float:
    """Mean NLL (standardised units) of `data` under the model in eval mode."""
    model.eval()
    y = torch.from_numpy(codec.encode(data.labels))
    total = 0.0
    for start in range(0, len(data), batch_size):
        index = slice(start, start + batch_size)
        x = inputs(data.depth_m(index)).to(device, channels_last)
        total += float(mdn_nll(model(*x), y[index].to(device), reduction="sum"))
    return total / max(len(data), 1)
