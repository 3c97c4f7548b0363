"""`model_card.md` of a training stage's output folder (train-mdn, train-segmenter,
train-hierarchy), written from plain data: its `model.json` and the stage's lines."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

MODEL_JSON = "model.json"
MODEL_CARD = "model_card.md"


def read_model_info(folder: Path) -> dict[str, Any]:
    """The `model.json` a training stage's chunk wrote into `folder`."""
    info: dict[str, Any] = json.loads((folder / MODEL_JSON).read_text())
    return info


def write_model_card(
    folder: Path,
    title: str,
    about: str,
    info: dict[str, Any],
    facts: Sequence[str],
    see: str,
    data_note: str = "",
) -> None:
    """`model_card.md`: `# title`, the `about` paragraph, then bullets: the training data
    (`info["data"]`: path and content hash, followed by `data_note`), the objects (when
    `info` counts them: held out from the training split), the `facts`, and where the
    config and the rest are (`see`: the per-epoch metrics files and more)."""
    data = info["data"]
    lines = [
        f"# {title}",
        "",
        about,
        "",
        f"- data: `{data['path']}` (content hash `{data['content_hash'][:16]}`){data_note}",
    ]
    if "n_train_objects" in info:
        lines.append(
            f"- objects: {info['n_train_objects']} train, {info['n_val_objects']} validation "
            "(held out from the training split; the test split is never used)"
        )
    lines += [*facts, f"- config: see manifest.json; per-epoch metrics: {see}", ""]
    (folder / MODEL_CARD).write_text("\n".join(lines))
