"""The graph labelling network as a compiled program, so inference need not import PyG.

Importing torch_geometric costs 1.5-4 s on this project's machines (its `__init__` imports
`torch._dynamo` and its dataset, loader and explain trees, whatever one uses): more than
everything else an `artic infer-hierarchy` run does. So the trained network (PyG's
`SAGEConv` and `EdgePooling`, thesis Fig. 4.4; `gnn.GraphLabellingNet`) is compiled with
`torch.jit.script` once per model file, and inference loads that program with
`torch.jit.load` (about 0.06 s, and neither PyG nor `torch._dynamo` is imported):

- **key**: a digest of the model file's bytes, of `gnn.py` (the code that is compiled) and
  of the torch and torch_geometric versions. Another model, an edit of the network's
  code or another library version gets another program, never a stale one.
- **where**: the shipped models' programs ship in the store (`models/compiled/<key>.pt`,
  written by `scripts/ship_model.py`; a test checks that every shipped labeller has its
  current program); any other model's program is compiled on first use into the user's
  cache (`$ARTIC_CACHE`, else `$XDG_CACHE_HOME/artic`, else `~/.cache/artic`:
  `compiled/<key>.pt`, written atomically, so concurrent runs at most compile twice; a
  cache that cannot be written only means compiling again next time). The first run of
  a newly trained model pays the PyG import once.
- **trust**: artic loads programs only from these two places, which only artic writes; a
  model file a user was given is still read as weights only (`model_file.py`) and compiled
  here from its state dict.
- **the same numbers**: the program runs the eager network's operations in the same order
  (tests check equal outputs to the last bit), so a tree does not depend on whether a
  program was cached. Training uses the eager network.

`torch.jit.script` is deprecated in torch 2.x in favour of `torch.export`, which cannot
express `EdgePooling`'s greedy edge contraction (a data-dependent loop); it still works on
the pinned torch, and its deprecation warning is silenced here.
"""

from __future__ import annotations

import hashlib
import io
import os
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from functools import cache
from importlib.metadata import version
from pathlib import Path

import torch

from artic.artifacts.hashing import sha256_file
from artic.artifacts.model_store import MODEL_FILE
from artic.artifacts.workdir import write_atomic
from artic.config.compose import models_dir

PROGRAMS = "compiled"


def cache_dir() -> Path:
    """The user's artic cache: `$ARTIC_CACHE`, else `$XDG_CACHE_HOME/artic`, else
    `~/.cache/artic`."""
    if os.environ.get("ARTIC_CACHE"):
        return Path(os.environ["ARTIC_CACHE"])
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "artic"


@cache
def _code_digest() -> str:
    from artic.hierarchy import gnn

    parts = [
        Path(gnn.__file__).read_bytes(),
        torch.__version__.encode(),
        version("torch_geometric").encode(),
    ]
    return hashlib.sha256(b"\0".join(parts)).hexdigest()


def program_key(model_file: Path) -> str:
    """The key of the program compiled from `model_file` with this artic and these libraries."""
    text = f"{sha256_file(model_file)}\0{_code_digest()}"
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def program_paths(key: str) -> tuple[Path, Path]:
    """Where the program of `key` may be: the shipped store's, then the user's cache."""
    name = f"{key}.pt"
    return models_dir() / PROGRAMS / name, cache_dir() / PROGRAMS / name


@contextmanager
def _jit_quietly() -> Iterator[None]:
    """torch.jit's deprecation warnings silenced (see the module's docstring)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning, message=".*torch.jit")
        yield


def compile_labeller(model: torch.nn.Module) -> bytes:
    """The TorchScript archive of `model` (a `GraphLabellingNet`, moved to the CPU)."""
    buffer = io.BytesIO()
    with _jit_quietly():
        program = torch.jit.script(model.cpu().eval())
        torch.jit.save(program, buffer)
    return buffer.getvalue()


def write_program(path: Path, archive: bytes) -> None:
    """Write atomically (`workdir.write_atomic`), making the folder first."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, archive)


def _load(source: Path | io.BytesIO) -> torch.jit.ScriptModule | None:
    """The program in `source`; None when it is missing or unreadable (then it is
    compiled again and replaced)."""
    if isinstance(source, Path) and not source.is_file():
        return None
    try:
        with _jit_quietly():
            return torch.jit.load(source, map_location="cpu")
    except (RuntimeError, ValueError, OSError):
        return None


def load_program(
    model_file: Path, build: Callable[[], torch.nn.Module], device: str | torch.device = "cpu"
) -> torch.jit.ScriptModule:
    """The compiled labeller of `model_file`, in evaluation mode on `device`: loaded from
    the store or the user's cache, else made by `build()` (the eager network with the
    file's weights), compiled, and cached (for this run only when the cache cannot be
    written)."""
    key = program_key(model_file)
    for path in program_paths(key):
        program = _load(path)
        if program is not None:
            return program.to(device).eval()
    archive = compile_labeller(build())
    with suppress(OSError):  # a read-only or full cache: the program serves this run only
        write_program(program_paths(key)[1], archive)
    program = _load(io.BytesIO(archive))
    if program is None:  # pragma: no cover - an archive torch has just written
        raise RuntimeError(f"{model_file}: the compiled labeller does not load")
    return program.to(device).eval()


def compile_shipped(store: Path | None = None) -> list[Path]:
    """Write the program of every shipped labeller (`<store>/hierarchy/*/model.pt`) into
    `<store>/compiled/`, and delete programs no shipped labeller has any more (of replaced
    models, or of an older `gnn.py` or library). For maintainers, after shipping a model or
    editing the network's code (`scripts/ship_model.py --programs`). Returns the programs."""
    from artic.hierarchy.models import load_labeller

    store = store or models_dir()
    folder = store / PROGRAMS
    wanted: list[Path] = []
    for model_file in sorted((store / "hierarchy").glob(f"*/{MODEL_FILE}")):
        path = folder / f"{program_key(model_file)}.pt"
        if not path.is_file():
            eager = load_labeller(model_file, compiled=False).model
            write_program(path, compile_labeller(eager))
        wanted.append(path)
    for stale in set(folder.glob("*.pt")) - set(wanted):
        stale.unlink()
    return wanted
