"""Shared fixtures: tiny datasets made once per test session, in temporary folders."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from artic.cli.main import app


def run_cli(*args: str) -> tuple[int, str, str]:
    """Run `artic ARGS...` in-process; returns (exit code, stdout, stderr)."""
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="session")
def tiny_objects(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny microwave object dataset (debug=tiny)."""
    out = tmp_path_factory.mktemp("objects") / "microwave"
    code, _, err = run_cli("generate-dataset", "debug=tiny", "category=microwave", f"out={out}")
    assert code == 0, err
    return out


@pytest.fixture(scope="session")
def tiny_depth(tiny_objects: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("depth") / "microwave"
    code, _, err = run_cli("render-depth", "debug=tiny", f"dataset={tiny_objects}", f"out={out}")
    assert code == 0, err
    return out
