"""`artic pipeline`: the smoke pipeline end to end, skipping, and malformed pipelines."""

from __future__ import annotations

from pathlib import Path

import pytest

from artic.artifacts.manifest import read_manifest
from cli_runner import run_cli


def test_smoke_pipeline_runs_then_skips(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the pipeline's relative outputs land in tmp_path
    code, out, err = run_cli("pipeline", "smoke")
    assert code == 0, err
    produced = sorted(
        p.parent.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("manifest.json")
    )
    assert "artifacts/smoke/depth/microwave" in produced
    assert "artifacts/smoke/objects/refrigerator" in produced
    assert (
        read_manifest(tmp_path / "artifacts/smoke/depth/refrigerator").config["render"]["backend"]
        == "pybullet"
    )
    # each stage's line echoes the command that runs it alone (issue 16)
    assert "artic evaluate bootstrap debug=tiny task=drawer" in out
    assert "artic evaluate-bootstrap" not in out
    assert "artic compose debug=tiny 'skills=[drawer]'" in out  # brackets are not markup
    assert (tmp_path / "artifacts/smoke/reports/compose/compose.csv").is_file()
    code, out, err = run_cli("pipeline", "smoke")
    assert code == 0, err
    assert "complete" not in out and out.count("up to date") + out.count("skipped") >= 6


def _write(tmp_path, text):
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("stages: {a: {cmd: train-everything}}", "unknown cmd 'train-everything'"),
        ("stages: {a: {cmd: render-depth, deps: [nowhere/x]}}", "dep nowhere/x"),
        ("stages: {a: {cmd: generate-dataset, bogus: 1}}", "stages.a.bogus"),
        ("stages: [", "not valid YAML"),
        (
            "stages: {a: {cmd: generate-dataset, overrides: [out=x/y], outs: [x/z]}}",
            "writes x/y, not listed in its outs",
        ),
    ],
)
def test_malformed_pipeline_exits_2(tmp_path, monkeypatch, text, message):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", _write(tmp_path, text))
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1


def test_unknown_pipeline_lists_known_ones():
    code, _, err = run_cli("pipeline", "nosuch")
    assert code == 2 and "smoke" in err


def test_dry_run_lists_stages(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run_cli("pipeline", "smoke", "--dry-run")
    assert code == 0 and "depth-drawer" in out and not (tmp_path / "artifacts").exists()


SHIPPED = sorted(p.stem for p in (Path(__file__).parents[2] / "stages").glob("*.yaml"))


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_pipeline_composes(name, tmp_path, monkeypatch):
    """A dry run composes and validates every stage's config (a bad override exits 2)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("pipeline", name, "--dry-run")
    assert code == 0, err
    assert "planned" in out


VARS_PIPELINE = """
vars: {category: microwave}
stages:
  objects:
    cmd: generate-dataset
    overrides: [debug=tiny, 'category=${category}', 'out=out/${category}']
    outs: ['out/${category}']
"""


def test_pipeline_variables_default_and_override(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = _write(tmp_path, VARS_PIPELINE)
    code, out, err = run_cli("pipeline", path, "--dry-run")
    assert code == 0, err
    assert "out/microwave" in out
    code, out, err = run_cli("pipeline", path, "category=drawer")
    assert code == 0, err
    assert read_manifest(tmp_path / "out/drawer").config["category"]["name"] == "drawer"
    assert not (tmp_path / "out/microwave").exists()


@pytest.mark.parametrize(
    ("assignment", "message"),
    [("color=red", "variable 'color' is not declared"), ("category", "expected NAME=VALUE")],
)
def test_bad_pipeline_variable_exits_2(tmp_path, monkeypatch, assignment, message):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("pipeline", _write(tmp_path, VARS_PIPELINE), assignment)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_echoed_commands_exist(tmp_path, monkeypatch):
    """`command_line` spells each smoke stage's command as the CLI has it."""
    from artic.cli.pipeline import command_line, load_pipeline
    from artic.cli.registry import resolve
    from artic.config.pipeline_file import pipeline_path

    pipeline = load_pipeline(pipeline_path("smoke"))
    commands = set()
    for spec in pipeline.stages.values():
        words = command_line(resolve(spec.cmd, spec.overrides), []).split()[1:]
        commands.add(tuple(words))
    assert ("evaluate", "bootstrap") in commands and ("evaluate-bootstrap",) not in commands
    for words in sorted(commands):
        code, _, err = run_cli(*words, "--help")
        assert code == 0, (words, err)


@pytest.mark.parametrize("name", ["smoke", "ch4_paper"])
def test_summary_is_readable_at_80_columns(tmp_path, monkeypatch, name):
    """Output paths relative to their common folder (in the title), never cut."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "80")
    code, out, err = run_cli("pipeline", name, "--dry-run")
    assert code == 0, err
    assert "…" not in out
    assert max(len(line) for line in out.splitlines()) <= 80
    root = "artifacts/smoke" if name == "smoke" else "artifacts/paper"
    assert f"outputs under {root}/" in out
    outs = [line.split("│")[3].strip() for line in out.splitlines() if line.startswith("│ ")]
    assert "reports/hierarchy/storage_furniture" in outs


def test_bootstrap_overrides_go_to_the_stages_that_take_them(tmp_path, monkeypatch):
    from artic.cli.pipeline import load_pipeline, stage_overrides
    from artic.config.pipeline_file import pipeline_path

    path = pipeline_path("bootstrap")
    given = stage_overrides(path, load_pipeline(path), ["seeds=2", "updates=10"])
    assert given["search-bootstrap"] == given["search-random"] == ["seeds=2", "updates=10"]
    assert given["demos"] == [] and given["dmp"] == []
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli("bootstrap", "--task", "drawer", "seeds=2", "updates=10", "--dry-run")
    assert code == 0, err
    assert "search-random" in out


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("seedz=2", "no stage takes key 'seedz'; did you mean seed or seeds?"),
        ("seeds", "expected KEY=VALUE"),
    ],
)
def test_bootstrap_override_no_stage_takes_exits_2(tmp_path, monkeypatch, override, message):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("bootstrap", "--task", "drawer", override, "--dry-run")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow  # 2.5 min: the whole chain; test_plan_demos covers the predicted stage fast
def test_bootstrap_with_the_predicted_model_runs_end_to_end(tmp_path, monkeypatch):
    """Algorithm 1 with perception in the loop on a fresh clone: no MDN trained here, the
    shipped drawer MDN estimates the drawer, demos are planned on it, and the chain (tiny
    preset) runs to the report, whose summary names the model source."""
    import csv
    import json

    monkeypatch.delenv("ARTIC_MODELS")
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli("bootstrap", "--task", "drawer", "debug=tiny", "model.source=predicted")
    assert code == 0, err
    demos = json.loads((tmp_path / "artifacts/demos/drawer/demos.json").read_text())
    assert demos["kinematic_model"]["source"] == "predicted"
    assert demos["kinematic_model"]["mdn"].endswith("models/mdn/drawer/model.pt")
    report = tmp_path / "artifacts/reports/bootstrap/drawer"
    with (report / "summary.csv").open(newline="") as f:
        rows = {r["init"]: r for r in csv.DictReader(f)}
    assert rows["bootstrap"]["model_source"] == "predicted"
    assert rows["random"]["baseline"] == "exploring"
    assert (report / "fig5_3.png").is_file()
