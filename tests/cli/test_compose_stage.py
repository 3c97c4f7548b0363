"""`artic compose` on the tiny preset (the drawer's grasp-candidates -> cip-demos ->
train-cip for cip_bc, then two sequences): outputs with the issue's columns, the same
command gives the same bytes, --perceive adds the perceived models' row, bad input exits
2 with one line, and the stage options read as overrides."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from artic.cli.main import _with_options
from artic.errors import InputError
from artic.planning.cip_compose import COMPOSE_COLUMNS, TRIAL_COLUMNS
from cli_runner import run_cli


class Skills:
    """The drawer's tiny chain (cip_bc only)."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.grasps = root / "grasps"
        self.policy = root / "policy"

    def compose(self, out: Path, *args: str) -> tuple[int, str, str]:
        return run_cli("compose", "--skills", "drawer", "debug=tiny", "bearings_deg=[-15.0]",
                       f"policies.drawer={self.policy}", f"grasps.drawer={self.grasps}",
                       f"out={out}", *args)  # fmt: skip


@pytest.fixture(scope="module")
def skills(tmp_path_factory: pytest.TempPathFactory) -> Skills:
    skills = Skills(tmp_path_factory.mktemp("compose"))
    demos = skills.root / "demos"
    code, _, err = run_cli("grasp-candidates", "--task", "drawer", "debug=tiny",
                           f"out={skills.grasps}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("cip-demos", "--task", "drawer", "debug=tiny",
                           f"initiation_set={skills.grasps}", f"out={demos}")  # fmt: skip
    assert code == 0, err
    code, _, err = run_cli("train-cip", "--task", "drawer", "debug=tiny", "settings=[cip_bc]",
                           f"initiation_set={skills.grasps}", f"demos={demos}",
                           f"out={skills.policy}")  # fmt: skip
    assert code == 0, err
    return skills


def test_compose_writes_trials_the_table_and_the_policies_hashes(skills, tmp_path):
    out = tmp_path / "compose"
    code, _, err = skills.compose(out)
    assert code == 0, err
    lines = (out / "compose.csv").read_text().splitlines()
    assert lines[0] == ",".join(COMPOSE_COLUMNS)
    assert len(lines) == 2 and lines[1].startswith("true,2,")
    trials = (out / "trials.csv").read_text().splitlines()
    assert trials[0] == ",".join(TRIAL_COLUMNS)
    assert [t.split(",")[:4] for t in trials[1:]] == [["0", "true", "0", "drawer"],
                                                      ["1", "true", "0", "drawer"]]  # fmt: skip
    ends = {t.split(",")[-1] for t in trials[1:]}
    assert ends <= {"success", "joint_limit", "contact_lost", "horizon", "no_grasp", "no_plan"}
    summary = json.loads((out / "summary.json").read_text())
    policy = summary["policies"]["drawer"]
    assert policy["unchanged"] is True and len(policy["sha256"]) == 64
    again = tmp_path / "again"
    assert skills.compose(again)[0] == 0
    for name in ("trials.csv", "compose.csv", "summary.json"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name


def test_perceive_adds_the_perceived_models(skills, tmp_path, monkeypatch):
    monkeypatch.delenv("ARTIC_MODELS")  # the shipped drawer MDN, as a user's run takes it
    out = tmp_path / "perceived"
    code, _, err = skills.compose(out, "--perceive", "trials=1")
    assert code == 0, err
    rows = [line.split(",") for line in (out / "compose.csv").read_text().splitlines()[1:]]
    assert [r[:2] for r in rows] == [["true", "1"], ["perceived", "1"]]


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["policies.drawer=/no/such/folder"], "/no/such/folder: no such folder"),
        (["setting=e2e"], "starts at home"),
        (["policy_seed=3"], "no policy of setting cip_bc, seed 3"),
        (["bearings_deg=[1.0,2.0]"], "bearings_deg: 2 values for 1 skills"),
        (["--skills"], "--skills: expects a value"),
        (["--perceive=yes"], "no such option: --perceive=yes"),
        (["--perceive"], "give one with perception.mdn.drawer"),  # tests ship no models
    ],
)
def test_bad_input_exits_2_with_one_line(skills, tmp_path, args, says):
    code, _, err = skills.compose(tmp_path / "bad", *args)
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "bad").exists()


def test_a_skill_of_another_task_is_refused(skills, tmp_path):
    code, _, err = run_cli("compose", "--skills", "door", "bearings_deg=[0.0]",
                           f"policies.door={skills.policy}", f"grasps.door={skills.grasps}",
                           f"out={tmp_path / 'bad'}")  # fmt: skip
    assert code == 2 and "holds task 'drawer'" in err, err


def test_stage_options_read_as_overrides():
    options = {"skills": "list", "perceive": "flag"}
    given = ["--skills", "door,drawer", "trials=3", "--perceive"]
    assert _with_options(given, options) == ["skills=[door,drawer]", "trials=3", "perceive=true"]
    assert _with_options(["a=1"], {}) == ["a=1"]
    with pytest.raises(InputError, match="no such option: --trials"):
        _with_options(["--trials", "3"], options)
