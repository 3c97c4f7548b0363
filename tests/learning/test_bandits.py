"""UCB1 over grasp candidates (Algorithm 3, select_grasp / update_success_rate)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from artic.errors import InputError
from artic.learning.bandits import UCB1

P = (0.2, 0.5, 0.8)


def run(pulls: int, seed: int) -> tuple[UCB1, list[int]]:
    rng = np.random.default_rng(seed)
    bandit, chosen = UCB1(len(P)), []
    for _ in range(pulls):
        arm = bandit.select()
        bandit.update(arm, float(rng.random() < P[arm]))
        chosen.append(arm)
    return bandit, chosen


def test_every_arm_is_tried_first_in_index_order():
    bandit = UCB1(5)
    order = []
    for _ in range(5):
        arm = bandit.select()
        bandit.update(arm, 1.0)  # even a success does not stop the others being tried
        order.append(arm)
    assert order == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_concentrates_on_the_best_bernoulli_arm(seed):
    bandit, chosen = run(2000, seed)
    counts = np.bincount(chosen, minlength=len(P))
    assert counts.argmax() == 2
    assert counts[2] > 0.7 * 2000
    assert np.all(counts > 0)
    assert abs(bandit.success_rates()[2] - P[2]) < 0.05


def test_the_bonus_is_c_sqrt_log_t_over_n():
    bandit = UCB1(2, c=1.0)
    bandit.update(0, 1.0)
    bandit.update(1, 0.0)
    bandit.update(1, 1.0)
    t = 3
    assert np.allclose(
        bandit.upper_bounds(), [1.0 + np.sqrt(np.log(t) / 1), 0.5 + np.sqrt(np.log(t) / 2)]
    )
    assert bandit.select() == 0


def test_state_round_trips_through_json_and_continues_identically():
    bandit, _ = run(300, 0)
    copy = UCB1.from_dict(json.loads(json.dumps(bandit.to_dict())))
    assert copy.to_dict() == bandit.to_dict()
    rng_a, rng_b = np.random.default_rng(9), np.random.default_rng(9)
    for _ in range(100):
        a, b = bandit.select(), copy.select()
        assert a == b
        bandit.update(a, float(rng_a.random() < P[a]))
        copy.update(b, float(rng_b.random() < P[b]))


def test_same_seed_same_choices():
    assert run(500, 3)[1] == run(500, 3)[1]
    assert json.dumps(run(500, 3)[0].to_dict()) == json.dumps(run(500, 3)[0].to_dict())


@pytest.mark.parametrize(
    ("state", "field"),
    [
        ({"pulls": [1, 2], "rewards": [1.0]}, "rewards"),
        ({"pulls": [1], "rewards": [2.0]}, "rewards[0]"),
        ({"pulls": [], "rewards": []}, "pulls"),
        ({"pulls": [1], "rewards": [1.0], "c": -1}, "c"),
        ({"pulls": [1], "rewards": [1.0], "extra": 0}, "extra"),
    ],
)
def test_a_malformed_state_is_an_input_error_naming_the_file_and_field(state, field):
    with pytest.raises(InputError, match=r"initiation_set\.json") as error:
        UCB1.from_dict(state, where="initiation_set.json")
    assert field in str(error.value)
    assert "\n" not in str(error.value)


def test_no_arm_and_bad_updates_are_refused():
    with pytest.raises(InputError, match="no arm"):
        UCB1(0)
    bandit = UCB1(2)
    with pytest.raises(ValueError, match="arm 2"):
        bandit.update(2, 1.0)
    with pytest.raises(ValueError, match="reward"):
        bandit.update(0, 1.5)
