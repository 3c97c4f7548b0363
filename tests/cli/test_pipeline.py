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
