"""`artic evaluate bootstrap video.enabled=true`: a GIF of each init's final policy,
listed in the manifest, the same bytes for the same seed, of the episode episodes.csv
reports; off by default.

Inputs: fake planned demos, the real fit-dmp and policy-search stages (tiny presets).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest
from PIL import Image
from test_policy_search import fit_dmp, write_plan_demos

from artic.artifacts.hashing import sha256_file
from artic.artifacts.manifest import read_manifest
from artic.learning.search_output import SearchOutput, VideoConfig, film_episode
from artic.sim.camera import CameraConfig
from cli_runner import run_cli

SMALL = ("video.camera.width=64", "video.camera.height=48")


@pytest.fixture(scope="module")
def tball_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("tball")
    demos = write_plan_demos(root / "demos", "tball")
    dmp = fit_dmp(demos, root / "dmp", "tball")
    runs = {}
    for init in ("bootstrap", "random"):
        out = root / init
        code, _, err = run_cli("policy-search", "debug=tiny", "task=tball", f"init={init}",
                               f"dmp={dmp}", "seeds=1", "updates=1", f"out={out}")  # fmt: skip
        assert code == 0, err
        runs[init] = out
    return runs


def gif_milliseconds(data: bytes) -> list[int]:
    """Each frame's duration; Pillow merges identical successive frames, adding them up."""
    gif = Image.open(io.BytesIO(data))
    durations = []
    for k in range(gif.n_frames):
        gif.seek(k)
        durations.append(int(gif.info["duration"]))
    return durations


def evaluate(runs: dict[str, Path], out: Path, *args: str) -> None:
    code, _, err = run_cli("evaluate", "bootstrap", "debug=tiny", "task=tball",
                           f"bootstrap={runs['bootstrap']}", f"random={runs['random']}",
                           f"out={out}", *args)  # fmt: skip
    assert code == 0, err


def test_video_is_off_by_default(tball_runs, tmp_path):
    evaluate(tball_runs, tmp_path / "plain")
    assert not list((tmp_path / "plain").glob("*.gif"))
    assert read_manifest(tmp_path / "plain").config["video"]["enabled"] is False


def test_video_of_each_final_policy_is_listed_and_deterministic(tball_runs, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    evaluate(tball_runs, first, "video.enabled=true", *SMALL)
    evaluate(tball_runs, second, "video.enabled=true", *SMALL)
    manifest = read_manifest(first)
    assert manifest.content_hash == read_manifest(second).content_hash
    horizon = SearchOutput.open(tball_runs["bootstrap"]).cfg.task.horizon  # tiny: short
    kept = horizon // 2 + 1  # frames after the reset and after each step, every 2nd kept
    for init in ("bootstrap", "random"):
        name = f"video_{init}.gif"
        data = (first / name).read_bytes()
        assert data == (second / name).read_bytes()  # same seed, same bytes
        assert manifest.outputs[name].sha256 == sha256_file(first / name)
        gif = Image.open(io.BytesIO(data))
        assert gif.format == "GIF" and gif.size == (64, 48) and gif.info["loop"] == 0
        # 20 Hz control, every 2nd frame: 10 frames/s, 100 ms each
        assert sum(gif_milliseconds(data)) == kept * 100


def test_the_film_is_episode_0_of_episodes_csv(tball_runs, tmp_path):
    out = tmp_path / "report"
    evaluate(tball_runs, out)
    with (out / "episodes.csv").open(newline="") as f:
        row = next(r for r in csv.DictReader(f) if r["init"] == "bootstrap")
    assert row["episode"] == "0" and row["seed"] == "0"
    run = SearchOutput.open(tball_runs["bootstrap"])
    video = VideoConfig(enabled=True, frame_every=5, camera=CameraConfig(width=32, height=24))
    traj, gif = film_episode(run.cfg.task, run.final_actor(0), int(row["reset_seed"]), video)
    assert traj.total_return == pytest.approx(float(row["return"]), rel=1e-9)
    horizon = run.cfg.task.horizon
    kept = len(range(0, horizon + 1, 5)) + (horizon % 5 != 0)  # 0, 5, ... and the last
    assert sum(gif_milliseconds(gif)) == kept * 250  # 4 frames/s
