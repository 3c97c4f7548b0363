"""The shared trainer: the epoch loop, early stopping, history, checkpoint and resume."""

from __future__ import annotations

import pytest
import torch

from artic.errors import InputError
from artic.learning import trainer
from artic.learning.fit_state import FitState


def _losses(values: list[float]):  # type: ignore[no-untyped-def]
    def run_epoch(epoch: int) -> trainer.EpochResult:
        return trainer.EpochResult(
            values[epoch], {"train_loss": 2.0 * epoch, "val_loss": values[epoch]}
        )

    return run_epoch


def test_fit_stops_early_keeps_the_best_weights_and_a_history_with_seconds_last() -> None:
    model = torch.nn.Linear(2, 1)
    seen: list[int] = []
    state = trainer.fit(
        model, FitState(), 10, 2, _losses([3.0, 1.0, 2.0, 2.5, 0.5]), lambda s: seen.append(s.epoch)
    )
    assert seen == [1, 2, 3, 4] and state.stopped_early and state.best_epoch == 2
    assert [list(h) for h in state.history] == [["epoch", "train_loss", "val_loss", "seconds"]] * 4
    assert state.best_weights is not None and state.best_weights.keys() == model.state_dict().keys()


def test_checkpoint_and_restore_round_trip() -> None:
    model = torch.nn.Linear(2, 1)
    optimizer = torch.optim.Adam(model.parameters())
    parts = {"model": model, "optimizer": optimizer}
    state = trainer.fit(model, FitState(), 2, 5, _losses([1.0, 0.5]), lambda s: None)
    saved = trainer.checkpoint(parts, state)
    assert set(saved) == {"model", "optimizer", "state"}
    other = torch.nn.Linear(2, 1)
    back = trainer.restore({"model": other, "optimizer": torch.optim.Adam(other.parameters())},
                           saved, FitState)  # fmt: skip
    assert back.epoch == 2 and back.best_val == 0.5
    assert all(
        torch.equal(a, b) for a, b in zip(model.parameters(), other.parameters(), strict=True)
    )
    assert trainer.restore(parts, None, FitState).epoch == 0


def test_train_config_and_device() -> None:
    cfg = trainer.TrainConfig(epochs=3, batch_size=4, lr=1e-3, patience=2, device="cpu", threads=1)
    threads = torch.get_num_threads()
    try:
        assert trainer.start_training(cfg) == torch.device("cpu") and torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(threads)
    with pytest.raises(ValueError):
        trainer.TrainConfig(epochs=0, batch_size=4, lr=1e-3, patience=2)
    if not torch.cuda.is_available():
        with pytest.raises(InputError, match=r"train\.device: cuda"):
            trainer.training_device("cuda")
