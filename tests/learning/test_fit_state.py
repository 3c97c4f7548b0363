"""FitState: early stopping, best weights, checkpoint round trip (old key names too)."""

from __future__ import annotations

import torch

from artic.learning.fit_state import FitState


def test_keeps_best_weights_and_stops_after_patience():
    model = torch.nn.Linear(2, 1)
    state = FitState()
    assert state.end_epoch(1.0, model, patience=2)
    best = {k: v.clone() for k, v in model.state_dict().items()}
    with torch.no_grad():
        model.weight.add_(1.0)  # later epochs change the weights
    assert not state.end_epoch(1.5, model, patience=2) and not state.stopped_early
    assert not state.end_epoch(1.2, model, patience=2) and state.stopped_early
    assert (state.epoch, state.best_epoch, state.best_val, state.bad_epochs) == (3, 1, 1.0, 2)
    assert state.best_weights is not None
    assert all(torch.equal(state.best_weights[k], best[k]) for k in best)


def test_round_trip_and_legacy_checkpoint_keys():
    state = FitState(epoch=4, best_val=0.5, best_epoch=3, history=[{"epoch": 1.0}])
    assert FitState.from_dict(state.to_dict()) == state
    legacy = {**state.to_dict(), "best_val_nll": 0.25}
    del legacy["best_val"]
    assert FitState.from_dict(legacy).best_val == 0.25
