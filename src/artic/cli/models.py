"""`artic models`: the model store as a table (or JSON): every shipped and locally trained
model, which one each command uses by default, and its figures."""

from __future__ import annotations

import json
from dataclasses import asdict

from artic.artifacts.model_store import KINDS, StoredModel, choose_model, list_models
from artic.errors import InputError


def _default_paths(models: list[StoredModel]) -> set[str]:
    """The model.pt each (kind, category) resolves to when no file is given."""
    chosen: set[str] = set()
    for kind, category in {(m.kind, m.category) for m in models}:
        try:
            chosen.add(str(choose_model(kind, category, None, "--model").path))
        except InputError:
            continue  # only debug models here, none shipped
    return chosen


def _figures(model: StoredModel) -> str:
    """The headline evaluation figures of a model (its kind's `headline`), or "-"."""
    headline = KINDS[model.kind].headline
    items = [(k, v) for k, v in model.figures.items() if headline in k]
    return "; ".join(f"{k} {v}" for k, v in items) or "-"


def show_models(as_json: bool) -> None:
    """Print the store: a Rich table, or with `as_json` one JSON document."""
    models = list_models()
    defaults = _default_paths(models)
    if as_json:
        rows = [
            {**asdict(m), "path": str(m.path), "debug": m.debug, "default": str(m.path) in defaults}
            for m in models
        ]
        print(json.dumps(rows, indent=2))
        return
    from rich.console import Console
    from rich.markup import escape

    console = Console()
    if not models:
        console.print("no models: none shipped, none under artifacts/models/")
        return
    console.print("artic models (* = used by default when no model file is given)")
    for m in models:
        kind = KINDS[m.kind]
        mark = "*" if str(m.path) in defaults else " "
        source = m.source + (", debug: never used by default" if m.debug else "")
        console.print(
            f"{mark} [bold]{m.kind}/{m.category}[/] ({source}, {m.size / 1e6:.1f} MB) "
            f"{escape(str(m.path))}",
            highlight=False,
        )
        lines = [
            f"used by: {kind.used_by} (Chapter {kind.chapter})",
            f"preset:  {m.preset}",
            f"config:  {m.config_hash[:12]}  data: {m.data_hash[:12] or '-'}  "
            f"commit: {m.commit or '-'}",
            f"figures: {_figures(m)}",
        ]
        for line in lines:
            console.print(f"    {escape(line)}", highlight=False)
