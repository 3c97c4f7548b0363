"""Files of a stage's resume folder (`WorkDir.resume_dir`): prepared data cached on first
use and search states saved after every update, so an interrupted chunk continues where
it stopped. The folder is specific to the config and input hashes, so nothing in it can
be stale; torch files are read with `weights_only=True`, and a corrupt one is an
InputError naming it (never silently discarded)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from artic.artifacts.formats import read_npz, replace_file, write_npz
from artic.errors import InputError

T = TypeVar("T")
Arrays = dict[str, Any]  # name -> array


def cached_npz(path: Path, make: Callable[[], Arrays]) -> Arrays:
    """The arrays `make()` returns, stored in `path` (.npz) on first use."""
    if path.is_file():
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    arrays = make()
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(tmp, **arrays)
    replace_file(tmp, path)
    return arrays


def cached_torch(
    path: Path, make: Callable[[], T], encode: Callable[[T], Any], decode: Callable[[Any], T]
) -> T:
    """`make()`, stored in `path` as the torch file of `encode(value)` (tensors and plain
    data) on first use, read back with `decode`."""
    from artic.artifacts.model_file import load_torch_file, save_torch_file

    if path.is_file():
        stored = load_torch_file(path, "checkpoint")
        try:
            return decode(stored)
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"{path}: not a readable checkpoint ({err})") from None
    value = make()
    save_torch_file(path, encode(value))
    return value


def load_state(path: Path) -> dict[str, Any] | None:
    """A search state saved by `save_state` (None: there is none yet)."""
    if not path.is_file():
        return None
    state = read_npz(path)
    state["n_updates"] = state["n_updates"].reshape(())  # write_npz stores it as (1,)
    return state


def save_state(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """A search state (arrays; `n_updates` a scalar), replacing the last atomically."""
    tmp = path.with_suffix(".tmp")
    write_npz(tmp, arrays, compress=False)
    replace_file(tmp, path)


def torch_checkpoint(
    path: Path, map_location: Any = "cpu"
) -> tuple[Any | None, Callable[[dict[str, Any]], None]]:
    """The checkpoint saved in `path` (None: none yet; read with `weights_only`, a corrupt
    one is an InputError naming it) and the function that saves the next one there."""
    from artic.artifacts.model_file import load_torch_file, save_torch_file

    saved = (
        load_torch_file(path, "checkpoint", map_location=map_location) if path.is_file() else None
    )
    return saved, lambda payload: save_torch_file(path, payload)
