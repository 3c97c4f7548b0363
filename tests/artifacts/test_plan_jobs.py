"""The library side of `artic pipeline NAME launcher=...` and of the pipeline summary,
without the CLI: which jobs a pipeline's stages become from their outputs' progress
(`artifacts.cluster.plan_jobs`), how far an output is from its inputs' manifests
(`artifacts.job_records.output_progress`), and the outputs' common folder
(`config.pipeline_file`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Literal

import pytest

from artic.artifacts.cluster import plan_jobs
from artic.artifacts.job_records import output_progress
from artic.artifacts.workdir import Progress
from artic.config.launcher import LauncherConfig, Resources
from artic.config.pipeline_file import PipelineStage, common_folder, relative_out
from artic.errors import InputError

LOCAL = LauncherConfig(name="local")


def _stage(
    cmd: str, deps: list[str], outs: list[str], shards: int | Literal["chunks"] = 1
) -> PipelineStage:
    return PipelineStage(cmd=cmd, deps=deps, outs=outs, resources=Resources(shards=shards))


def _progress(
    states: dict[str, Progress],
) -> tuple[Callable[[str, int], Progress], list[tuple[str, int]]]:
    """A progress callback answering from `states`, and the questions it was asked."""
    asked: list[tuple[str, int]] = []

    def progress(name: str, shards: int) -> Progress:
        asked.append((name, shards))
        return states[name]

    return progress, asked


def test_an_up_to_date_stage_is_skipped_unless_its_input_is_made_again() -> None:
    planned = [
        ("data", _stage("generate-dataset", [], ["out/data"]), "generate-dataset", "out/data"),
        ("train", _stage("train-mdn", ["out/data"], ["out/model"]), "train-mdn", "out/model"),
    ]
    done = {n: Progress(Path(o), "done", [], 1, 1) for n, *_, o in planned}
    progress, _ = _progress(done)
    assert plan_jobs(Path("p.yaml"), planned, LOCAL, False, progress) == []
    # data not done: both are submitted, train whole although its own output is done
    progress, _ = _progress({**done, "data": Progress(Path("out/data"), "none", [0], 0, 1)})
    jobs = plan_jobs(Path("p.yaml"), planned, LOCAL, False, progress)
    assert [(j.name, j.stage, j.out, j.shards, j.todo) for j in jobs] == [
        ("data", "generate-dataset", Path("out/data"), 1, [0]),
        ("train", "train-mdn", Path("out/model"), 1, [0]),
    ]
    progress, _ = _progress(done)
    assert len(plan_jobs(Path("p.yaml"), planned, LOCAL, True, progress)) == 2  # force


def test_a_sharded_stage_gets_its_missing_shards_and_too_many_shards_are_refused() -> None:
    planned = [("render", _stage("render-depth", [], [], shards=4), "render-depth", "out/r")]
    states = {"render": Progress(Path("out/r"), "partial", [1, 3], 6, 8)}
    progress, asked = _progress(states)
    (job,) = plan_jobs(Path("p.yaml"), planned, LOCAL, False, progress)
    assert (job.shards, job.todo) == (4, [1, 3])
    assert asked == [("render", 1), ("render", 4)]
    states["render"] = Progress(Path("out/r"), "none", [0], 0, 2)
    with pytest.raises(
        InputError, match=r"p\.yaml: stage render \(render-depth\) has fewer chunks; asked for 4"
    ):
        plan_jobs(Path("p.yaml"), planned, LOCAL, False, progress)
    planned = [("train", _stage("train-mdn", [], [], shards="chunks"), "train-mdn", "out/t")]
    progress, _ = _progress({"train": Progress(Path("out/t"), "waiting")})
    with pytest.raises(InputError, match="shards: chunks, but its plan needs inputs"):
        plan_jobs(Path("p.yaml"), planned, LOCAL, False, progress)


def test_an_output_waits_for_inputs_without_a_manifest(tmp_path: Path) -> None:
    (tmp_path / "data").mkdir()
    out = tmp_path / "out"
    waiting = output_progress(out, "h", lambda: {"dataset": tmp_path / "data"}, 3, 1)
    assert (waiting.state, waiting.n_chunks) == ("waiting", 3)

    def unreadable() -> dict[str, Path]:
        raise InputError("dataset: no such folder")

    assert output_progress(out, "h", unreadable, None, 1).state == "waiting"
    nothing = output_progress(out, "h", dict, 3, 2)  # no inputs, nothing written yet
    assert (nothing.state, nothing.missing) == ("none", [0, 1])


def test_outputs_relative_to_their_common_folder() -> None:
    outs = ["artifacts/smoke/data", "artifacts/smoke/reports/mdn"]
    common = common_folder(outs)
    assert common == "artifacts/smoke"
    assert [relative_out(o, common) for o in outs] == ["data", "reports/mdn"]
    assert common_folder(["a/x"]) == "" and common_folder(["/abs/x", "rel/y"]) == ""
    assert common_folder(["x", "y"]) == "" and relative_out("x", "") == "x"
