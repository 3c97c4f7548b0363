"""`artic pipeline`: the smoke pipeline end to end, skipping, and malformed pipelines."""

from __future__ import annotations

import pytest

from artic.artifacts.manifest import read_manifest
from conftest import run_cli


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
