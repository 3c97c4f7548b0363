"""`model.pt`: a trained network with everything needed to use it.

A dict saved with `torch.save`: `format`, `kind` (what the network is), `artic_version`,
`category`, `hparams` (constructor arguments), `state_dict`, and kind-specific `meta`
(for the MDN: the target codec, the training camera, the label columns, the data it was
trained on). `load_model_file` refuses, by name, a file of another kind, another
category or an incompatible format, instead of loading it silently.

Safe loading: a model file is something a user may have been given, and unpickling runs
whatever code the file names. So every file artic reads back with `torch.load` (model
files, and the checkpoints in work areas) is loaded with `weights_only=True`, and may
contain only tensors, dicts, lists, tuples, str, int, float, bool and None (`plain`
checks this, and converts numpy scalars and arrays, when saving). A file that holds
anything else (a pickled object of any class, numpy arrays of an older artic) is
refused with `InputError` (exit 2) naming it, without running anything from it; so is a
truncated or corrupt file.
"""

from __future__ import annotations

import os
import pickle
import warnings
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np

from artic import __version__
from artic.errors import InputError

FORMAT = 1

#: the scalar types a saved payload may hold (exactly these types, not subclasses such as
#: numpy.float64, which pickles as a numpy object)
_SCALARS = (str, int, float, bool, type(None))


def plain(value: Any, where: str = "payload") -> Any:
    """`value` as data `torch.load(weights_only=True)` reads back unchanged: tensors,
    dicts (str/int keys), lists, tuples and str/int/float/bool/None are kept; numpy bool,
    int and float scalars become the Python scalar of the same value, such arrays nested
    lists of them (exact: float64 -> float, float32 -> float of the same value). Anything else is a
    programming error: TypeError naming where in the payload it is."""
    import torch

    if type(value) in _SCALARS or isinstance(value, torch.Tensor):
        return value
    numeric = isinstance(value, np.generic | np.ndarray) and value.dtype.kind in "biuf"
    if numeric and value.dtype.itemsize <= 8:  # not longdouble: its .item() stays numpy
        return value.item() if isinstance(value, np.generic) else value.tolist()
    if type(value) in (dict, OrderedDict):  # OrderedDict: a state dict, with `_metadata`
        out = type(value)()
        for k, v in value.items():
            if type(k) not in (str, int):
                raise TypeError(f"{where}: key {k!r} of type {type(k).__name__}")
            out[k] = plain(v, f"{where}[{k!r}]")
        if hasattr(value, "_metadata"):
            out._metadata = plain(value._metadata, f"{where}._metadata")
        return out
    if type(value) in (list, tuple):
        items = [plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
        return items if type(value) is list else tuple(items)
    raise TypeError(f"{where}: {type(value).__name__} cannot be saved in a safe torch file")


def save_torch_file(path: Path, payload: dict[str, Any]) -> None:
    """`plain(payload)` with `torch.save`, atomically (temporary file, then rename)."""
    import torch

    safe = plain(payload)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(safe, tmp)
    os.replace(tmp, path)


def load_torch_file(path: Path, what: str = "model file", map_location: Any = "cpu") -> Any:
    """`torch.load(path, weights_only=True)`; InputError naming `path` when it holds
    anything but tensors and plain data (nothing from it is run) or is unreadable."""
    import torch

    try:
        with warnings.catch_warnings():  # e.g. "Detected pickle protocol 4" of a plain pickle
            warnings.simplefilter("ignore")
            return torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as err:
        if str(err).startswith("Weights only load failed"):
            raise InputError(
                f"{path}: not a safe artic {what} (refused: contains objects other than "
                "tensors and plain data)"
            ) from None
        raise InputError(f"{path}: not a readable {what} (corrupt or truncated)") from None
    except Exception as err:  # torch raises many types for a truncated or corrupt file
        raise InputError(
            f"{path}: not a readable {what} (corrupt or truncated: {type(err).__name__})"
        ) from None


def save_model_file(
    path: Path,
    kind: str,
    category: str,
    hparams: dict[str, Any],
    state_dict: dict[str, Any],
    meta: dict[str, Any],
) -> None:
    """Write atomically (temporary file, then rename); hparams and meta must be plain
    data (`plain`), the state dict tensors."""
    payload = {
        "format": FORMAT,
        "kind": kind,
        "artic_version": __version__,
        "category": category,
        "hparams": hparams,
        "state_dict": state_dict,
        "meta": meta,
    }
    save_torch_file(path, payload)


def half_precision(state_dict: dict[str, Any]) -> dict[str, Any]:
    """`state_dict` with every float32 / float64 tensor stored as float16 (half the bytes;
    integer tensors such as BatchNorm's step counter unchanged), for shipping. Loading
    casts back: `Module.load_state_dict` copies into the module's float32 parameters, so
    the network computes in float32 on rounded weights (relative rounding <= 2^-11).
    ValueError naming the tensor when a value would not survive (beyond float16's range,
    or NaN/inf)."""
    import torch

    out = type(state_dict)()
    for name, value in state_dict.items():
        if isinstance(value, torch.Tensor) and value.dtype in (torch.float32, torch.float64):
            half = value.to(torch.float16)
            if not bool(torch.isfinite(half).all()):
                raise ValueError(f"{name}: values beyond float16's range (or not finite)")
            value = half
        out[name] = value
    if hasattr(state_dict, "_metadata"):
        out._metadata = state_dict._metadata  # type: ignore[attr-defined]
    return out


def load_model_file(path: Path, kind: str, category: str | None = None) -> dict[str, Any]:
    """The saved dict, after checking format, kind and (if given) category; loaded with
    `weights_only=True` (`load_torch_file`)."""
    if not path.is_file():
        raise InputError(f"{path}: no such model file")
    payload = load_torch_file(path, "model file")
    if not isinstance(payload, dict) or "kind" not in payload:
        raise InputError(f"{path}: not an artic model file")
    if payload.get("format") != FORMAT:
        raise InputError(
            f"{path}: model file format {payload.get('format')} (artic "
            f"{payload.get('artic_version')}); this artic reads format {FORMAT}"
        )
    if payload["kind"] != kind:
        raise InputError(f"{path}: a {payload['kind']} model, not a {kind} model")
    if category is not None and payload.get("category") != category:
        raise InputError(f"{path}: a model of category {payload.get('category')}, not {category}")
    return payload
