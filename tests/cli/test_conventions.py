"""CLI conventions: `--cfg` validates as the run does, a mistyped override key suggests
the closest keys, shell completion answers, the README's example files exist."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from artic.config.compose import config_keys
from cli_runner import run_cli

ROOT = Path(__file__).parents[2]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["train-mdn", "trian.epochs=3"],
         "no key 'trian.epochs' in the train-mdn config; did you mean train.epochs?"),
        (["generate-dataset", "dataset.object=3"], "did you mean dataset.objects"),
        (["evaluate", "mdn", "evaluate.icp_image=3"], "did you mean evaluate.icp_images"),
        (["train-mdn", "zzz=1"], "no key 'zzz' in the train-mdn config"),
    ],
)  # fmt: skip
def test_a_mistyped_key_suggests_the_closest(args, fragment, tmp_path):
    code, _, err = run_cli(*args, f"out={tmp_path / 'o'}")
    assert code == 2, err
    (line,) = err.strip().splitlines()
    assert fragment in line and "+" not in line
    assert not (tmp_path / "o").exists()


def test_cfg_validates_as_the_run_does():
    code, out, err = run_cli("train-mdn", "train.epochs=-3", "--cfg")
    assert code == 2 and "train.epochs" in err and out == ""
    code, out, err = run_cli("train-mdn", "train.epochs=3", "--cfg")
    assert code == 0, err
    assert "epochs: 3" in out


def test_config_keys_are_dotted_paths():
    assert config_keys({"a": 1, "b": {"c": 2, "d": {"e": 3}}}) == ["a", "b", "b.c", "b.d", "b.d.e"]


def _complete(words: str) -> list[str]:
    env = {**os.environ, "_ARTIC_COMPLETE": "complete_bash", "COMP_WORDS": words,
           "COMP_CWORD": str(len(words.split(" ")) - 1)}  # fmt: skip
    artic = Path(sys.executable).parent / "artic"
    done = subprocess.run([str(artic)], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_shell_completion_names_commands_and_groups():
    assert _complete("artic pre") == ["predict"]
    assert {"mdn", "hierarchy", "bootstrap"} <= set(_complete("artic evaluate "))
    assert "models" in _complete("artic mod")


def test_the_readme_names_files_that_exist():
    """Every `--camera FILE.json` of the README and docs/ is in the repository, or a
    camera preset of conf/common/camera/."""
    presets = {p.stem for p in (ROOT / "conf/common/camera").glob("*.yaml")}
    texts = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    seen = 0
    for path in texts:
        for value in re.findall(r"--camera ([\w./-]+)", path.read_text()):
            seen += 1
            if value.endswith(".json"):
                assert (ROOT / value).is_file(), f"{path.name}: --camera {value} does not exist"
            else:
                assert value in presets or value.isupper(), f"{path.name}: --camera {value}"
    assert seen >= 2
