"""The compiled graph labelling network (`artic.hierarchy.compiled`): the same outputs as
the eager network, cached by key, loaded without importing PyG, shipped up to date."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from artic.errors import InputError
from artic.hierarchy import compiled
from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig, predict
from artic.hierarchy.graph import PartGraphConfig, build_part_graph
from artic.hierarchy.models import LABELLER_KIND, load_labeller, save_labeller
from artic.hierarchy.types import PartGraph

TINY = GraphNetConfig(encoder_widths=(8, 16), decoder_points=16, hidden=16, head_hidden=16)
STORE = Path(__file__).parents[2] / "models"


def _graph(parts: int, seed: int) -> PartGraph:
    """`parts` blobs of points, close enough that most pairs touch (edges), or one part."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0.0, 1.0, (parts, 3))
    points = np.concatenate([c + rng.uniform(-0.2, 0.2, (40, 3)) for c in centres])
    part_id = np.repeat(np.arange(parts), 40)
    cfg = PartGraphConfig(contact_threshold=0.3, points_per_node=16)
    return build_part_graph(points, part_id, rng, cfg)


@pytest.fixture(autouse=True)
def own_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test its own cache (the session's is shared, and these models alike)."""
    monkeypatch.setenv("ARTIC_CACHE", str(tmp_path / "cache"))


@pytest.fixture
def model_file(tmp_path: Path) -> Path:
    torch.manual_seed(3)
    path = tmp_path / "model.pt"
    save_labeller(path, "lamp", GraphLabellingNet(TINY), PartGraphConfig(), {})
    return path


def test_the_program_gives_the_eager_networks_outputs_to_the_last_bit(model_file: Path) -> None:
    program = load_labeller(model_file).model
    eager = load_labeller(model_file, compiled=False).model
    assert isinstance(program, torch.jit.ScriptModule)
    for parts, seed in [(1, 0), (2, 1), (3, 2), (6, 3), (11, 4)]:
        graph = _graph(parts, seed)
        a, b = predict(program, graph), predict(eager, graph)
        for field in ("motion", "exists", "parent_first", "root"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), (parts, field)


def test_compiled_once_then_loaded_from_the_cache(
    model_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    key = compiled.program_key(model_file)
    cached = compiled.cache_dir() / compiled.PROGRAMS / f"{key}.pt"
    assert not cached.exists()
    load_labeller(model_file)
    assert cached.is_file()

    def no_compiling(model: torch.nn.Module) -> bytes:
        raise AssertionError("compiled again")

    monkeypatch.setattr(compiled, "compile_labeller", no_compiling)
    assert isinstance(load_labeller(model_file).model, torch.jit.ScriptModule)


def test_a_cache_that_cannot_be_written_only_costs_compiling_again(
    model_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    monkeypatch.setenv("ARTIC_CACHE", str(blocked))  # compiled/ cannot be made under it
    graph = _graph(4, 1)
    got = predict(load_labeller(model_file).model, graph)
    want = predict(load_labeller(model_file, compiled=False).model, graph)
    assert np.array_equal(got.parent_first, want.parent_first)
    assert blocked.read_text() == ""


def test_another_model_file_another_program(model_file: Path, tmp_path: Path) -> None:
    other = tmp_path / "other.pt"
    save_labeller(other, "lamp", GraphLabellingNet(TINY), PartGraphConfig(), {"x": 1})
    assert compiled.program_key(other) != compiled.program_key(model_file)


def test_a_broken_cached_program_is_compiled_again(model_file: Path) -> None:
    key = compiled.program_key(model_file)
    cached = compiled.cache_dir() / compiled.PROGRAMS / f"{key}.pt"
    cached.parent.mkdir(parents=True, exist_ok=True)
    cached.write_bytes(b"not a torchscript archive")
    graph = _graph(3, 0)
    got = predict(load_labeller(model_file).model, graph)
    want = predict(load_labeller(model_file, compiled=False).model, graph)
    assert np.array_equal(got.exists, want.exists)
    assert cached.read_bytes()[:2] == b"PK"  # a zip archive again


def test_weights_that_do_not_fit_are_refused_by_name(model_file: Path) -> None:
    payload = torch.load(model_file, weights_only=True)
    payload["hparams"]["network"]["hidden"] = 24
    torch.save(payload, model_file)
    with pytest.raises(InputError, match=f"{model_file}: labeller does not load"):
        load_labeller(model_file)
    assert payload["kind"] == LABELLER_KIND


def test_a_cached_program_loads_without_importing_pyg(model_file: Path) -> None:
    """The point of compiling: PyG's import costs seconds (docs/benchmarks.md)."""
    load_labeller(model_file)  # compile into the cache
    code = (
        "import sys; from pathlib import Path; "
        "from artic.hierarchy.models import load_labeller; "
        f"load_labeller(Path({str(model_file)!r})); "
        "heavy = ('torch_geometric', 'torch._dynamo'); "
        "print(sorted(m for m in sys.modules if m.startswith(heavy)))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=os.environ.copy()
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_every_shipped_labeller_ships_its_current_program() -> None:
    """Fails after an edit of gnn.py or a new shipped labeller until the programs are
    compiled again: `python scripts/ship_model.py --programs`."""
    labellers = sorted((STORE / "hierarchy").glob("*/model.pt"))
    assert labellers
    have = {p.name for p in (STORE / compiled.PROGRAMS).glob("*.pt")}
    want = {f"{compiled.program_key(m)}.pt" for m in labellers}
    assert have == want, "run: python scripts/ship_model.py --programs"


def test_compile_shipped_writes_the_current_programs_and_drops_stale_ones(
    model_file: Path, tmp_path: Path
) -> None:
    store = tmp_path / "store"
    (store / "hierarchy" / "lamp").mkdir(parents=True)
    (store / "hierarchy" / "lamp" / "model.pt").write_bytes(model_file.read_bytes())
    stale = store / compiled.PROGRAMS / "0123.pt"
    stale.parent.mkdir()
    stale.write_bytes(b"old")
    written = compiled.compile_shipped(store)
    assert [p.name for p in written] == [f"{compiled.program_key(model_file)}.pt"]
    assert not stale.exists() and written[0].is_file()
