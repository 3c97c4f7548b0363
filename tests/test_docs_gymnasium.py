"""docs/gymnasium.md's stable-baselines3 example runs as written, with fewer steps: the
code is read from the doc, so the doc cannot drift from the code."""

from __future__ import annotations

import io
import re
from pathlib import Path

from PIL import Image

DOC = Path(__file__).resolve().parents[1] / "docs" / "gymnasium.md"
SECTION = "## Train a stable-baselines3 agent"


def example_code() -> str:
    """The ```python blocks of the doc's stable-baselines3 section, in order."""
    text = DOC.read_text()
    section = text[text.index(SECTION) :]
    section = section[: section.find("\n## ", len(SECTION))]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)
    assert len(blocks) == 2, "the section shows the training and the filming"
    return "\n".join(blocks)


def shrink(code: str, old: str, new: str) -> str:
    assert code.count(old) >= 1, f"the doc's example no longer says {old!r}"
    return code.replace(old, new)


def test_the_stable_baselines3_example_trains_saves_and_films(tmp_path, monkeypatch, capsys):
    code = shrink(example_code(), "total_timesteps=30_000", "total_timesteps=64")
    # one PPO rollout of 64 steps and one epoch instead of 2048 steps and ten
    code = shrink(code, 'device="cpu")', 'device="cpu", n_steps=64, batch_size=32, n_epochs=1)')
    code = shrink(code, "n_eval_episodes=10", "n_eval_episodes=1")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3"))  # not the system's tmp folder
    exec(compile(code, str(DOC), "exec"), {"__name__": "docs_gymnasium"})
    printed = capsys.readouterr().out
    assert re.search(r"mean return -\d+ before, -\d+ after training", printed), printed
    assert re.search(r"ball moved -?\d+\.\d\d m, success: (True|False)", printed), printed
    assert (tmp_path / "ppo_tball.zip").is_file()
    gif = Image.open(io.BytesIO((tmp_path / "ppo_tball.gif").read_bytes()))
    assert gif.format == "GIF" and gif.size == (320, 240)
    total = 0
    for k in range(gif.n_frames):  # identical successive frames are merged: add durations
        gif.seek(k)
        total += int(gif.info["duration"])
    assert total == 61 * 50  # the reset and 60 steps at 20 frames/s
