"""`run_cli`: the CLI in-process through Typer's runner, for tests.

A module of its own (not conftest.py): `from conftest import ...` resolves to whichever
conftest.py pytest imported first, and tests/objects has one too.
"""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from artic.cli.main import app


def run_cli(*args: str) -> tuple[int, str, str]:
    """Run `artic ARGS...` in-process; returns (exit code, stdout, stderr)."""
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def train_tiny_mdn(depth: Path, out: Path) -> Path:
    """`artic train-mdn debug=tiny category=microwave` on the render-depth folder `depth`
    into `out`; returns `out`."""
    code, _, err = run_cli(
        "train-mdn", "debug=tiny", "category=microwave", f"depth={depth}", f"out={out}"
    )
    assert code == 0, err
    return out
