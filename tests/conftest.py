"""Shared fixtures: tiny datasets made once per test session, in temporary folders."""

from __future__ import annotations

from pathlib import Path

from artic.reproducibility import numerics_loaded_too_early, pin_numerics

# the tests run the CLI in this process: pin the numerical kernels as `artic` does, before
# NumPy or PyTorch is imported (artic.reproducibility)
assert not numerics_loaded_too_early(), numerics_loaded_too_early()
pin_numerics()

import pytest  # noqa: E402

from cli_runner import run_cli, train_tiny_mdn  # noqa: E402


@pytest.fixture(autouse=True)
def no_shipped_models(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch):
    """Tests see an empty shipped model store (`ARTIC_MODELS`), so what ships cannot change
    what they check; tests of the real store delete the variable."""
    monkeypatch.setenv("ARTIC_MODELS", str(tmp_path_factory.getbasetemp() / "no-shipped-models"))


@pytest.fixture(autouse=True)
def own_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch):
    """Tests write artic's user cache (compiled labellers) to the session's temporary
    folder (`ARTIC_CACHE`), never to the home directory."""
    monkeypatch.setenv("ARTIC_CACHE", str(tmp_path_factory.getbasetemp() / "artic-cache"))


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


@pytest.fixture(scope="session")
def tiny_model(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A train-mdn output (microwave, debug=tiny) on `tiny_depth`; read, never changed."""
    return train_tiny_mdn(tiny_depth, tmp_path_factory.mktemp("mdn") / "microwave")
