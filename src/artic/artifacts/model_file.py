"""`model.pt`: a trained network with everything needed to use it.

A dict saved with `torch.save`: `format`, `kind` (what the network is), `artic_version`,
`category`, `hparams` (constructor arguments), `state_dict`, and kind-specific `meta`
(for the MDN: the target codec, the training camera, the label columns, the data it was
trained on). `load_model_file` refuses, by name, a file of another kind, another
category or an incompatible format, instead of loading it silently.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from artic import __version__
from artic.errors import InputError

FORMAT = 1


def save_model_file(
    path: Path,
    kind: str,
    category: str,
    hparams: dict[str, Any],
    state_dict: dict[str, Any],
    meta: dict[str, Any],
) -> None:
    """Write atomically (temporary file, then rename)."""
    import torch

    payload = {
        "format": FORMAT,
        "kind": kind,
        "artic_version": __version__,
        "category": category,
        "hparams": hparams,
        "state_dict": state_dict,
        "meta": meta,
    }
    tmp = path.with_name(path.name + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, path)


def load_model_file(path: Path, kind: str, category: str | None = None) -> dict[str, Any]:
    """The saved dict, after checking format, kind and (if given) category."""
    import torch

    if not path.is_file():
        raise InputError(f"{path}: no such model file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as err:  # torch raises many types for a bad file
        raise InputError(f"{path}: not a readable model file ({type(err).__name__})") from None
    if not isinstance(payload, dict) or "kind" not in payload:
        raise InputError(f"{path}: not an artic model file")
    if payload.get("format") != FORMAT:
        raise InputError(
            f"{path}: model file format {payload.get('format')} (artic "
            f"{payload.get('artic_version')}); this artic reads format {FORMAT}"
        )
    if payload["kind"] != kind:
        raise InputError(f"{path}: a {payload['kind']} model, not a {kind} model")
    if category is not None and payload["category"] != category:
        raise InputError(f"{path}: a model of category {payload['category']}, not {category}")
    return payload
