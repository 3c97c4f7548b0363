"""Put a trained model into the shipped model store (`models/`), for maintainers.

    python scripts/ship_model.py artifacts/models/mdn/microwave \
        --evaluation artifacts/reports/mdn/microwave

Copies the training output's model.pt, writes card.json (preset, config and data hashes,
the commit it was trained at, the evaluation's figures) and model_card.md with the
figures appended (`artic.artifacts.model_store.ship_model`). The commit is read with git
from the checkout the model folder lies in; a model trained with a debug preset is
refused. docs/models.md says how the shipped models were made.

    python scripts/ship_model.py models/mdn/drawer --evaluation REPORT

re-cards a model already shipped (its folder has a card.json): the figures of a new
`artic evaluate mdn model=models/mdn/drawer` and its refined_intervals.csv
(`artic.artifacts.model_store.recard_shipped`); the model file stays.

    python scripts/ship_model.py models/mdn/drawer --half

stores a shipped model's weights in half precision (`artic.artifacts.model_store.
halve_shipped`): half the bytes; its card loses the figures measured on the old bytes, so
evaluate it again and re-card it as above (docs/models.md).

    python scripts/ship_model.py models/segmenter/storage_furniture --inference passes=3

changes a shipped segmenter's saved inference settings (`artic.artifacts.model_store.
set_inference_shipped`; the weights stay); as with --half, evaluate it again and re-card it.

    python scripts/ship_model.py models/segmenter/office_chair --axis-head SCANS

fits an axis head onto a shipped votes segmenter (`artic.hierarchy.fit_segmenter.
axis_head_payload`: the head alone, on the training objects of the scan folder SCANS,
every other weight kept) and turns `inference.axis_split` on; as with --half, evaluate it
again and re-card it (docs/hierarchy.md, "One axis per part").

Every run also brings the shipped labellers' compiled programs (`models/compiled/`,
`artic.hierarchy.compiled`) up to date; `python scripts/ship_model.py --programs` does
only that (needed after an edit of `artic/hierarchy/gnn.py`: a test says so).
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path
from typing import Any

from artic.artifacts.model_store import (
    CARD_JSON,
    MANIFEST,
    halve_shipped,
    recard_shipped,
    set_inference_shipped,
    ship_model,
    transform_shipped,
)
from artic.errors import InputError
from artic.hierarchy.compiled import compile_shipped

STORE = Path(__file__).resolve().parents[1] / "models"


def _commit(folder: Path) -> str:
    """The commit of the git checkout `folder` is in ("unknown" outside one)."""
    done = subprocess.run(
        ["git", "-C", str(folder), "rev-parse", "--short=12", "HEAD"],
        capture_output=True,
        text=True,
    )
    return done.stdout.strip() if done.returncode == 0 else "unknown"


def _settings(pairs: list[str], parser: argparse.ArgumentParser) -> dict[str, Any]:
    """KEY=VALUE pairs -> {key: value}, each value read as JSON where it parses."""
    settings: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            parser.error(f"--inference: expected KEY=VALUE, got {pair!r}")
        try:
            settings[key] = json.loads(value)
        except json.JSONDecodeError:
            settings[key] = value
    return settings


def _inference_settings(settings: dict[str, Any]) -> dict[str, Any]:
    """A segmenter's inference settings, validated as a training saves them."""
    from artic.hierarchy.config import InferenceConfig

    return InferenceConfig(**settings).model_dump()


def _add_axis_head(folder: Path, scans: Path, args: argparse.Namespace) -> Path:
    """`transform_shipped` with `axis_head_payload`; prints what the fit did."""
    from artic.artifacts.manifest import read_manifest
    from artic.hierarchy.config import CloudDataConfig
    from artic.hierarchy.fit_segmenter import axis_head_payload

    data = CloudDataConfig(max_poses=args.axis_poses)

    def transform(payload: dict[str, Any]) -> dict[str, Any]:
        new, fit = axis_head_payload(payload, scans, data, args.axis_epochs, args.seed)
        losses = ", ".join(f"{loss:.4f}" for loss in fit.losses)
        print(  # noqa: T201
            f"axis head: losses {losses}; validation accuracy {fit.val_accuracy:.4f} "
            f"(parts weighing the same: {fit.val_part_accuracy:.4f})"
        )
        return new

    change = (
        f"axis head fitted (the rest frozen) on `{scans}` (content hash "
        f"`{read_manifest(scans).content_hash[:16]}`), its training objects' first "
        f"{args.axis_poses} poses, "
        f"{args.axis_epochs} epochs, seed {args.seed}; inference.axis_split on"
    )
    return transform_shipped(folder, transform, change)


def main() -> None:
    parser = argparse.ArgumentParser(description="ship a trained model with its card")
    parser.add_argument(
        "folder",
        type=Path,
        nargs="?",
        help="a train-mdn / train-segmenter / train-hierarchy output",
    )
    parser.add_argument(
        "--programs", action="store_true", help="only compile the shipped labellers' programs"
    )
    parser.add_argument("--evaluation", type=Path, help="the evaluate output of this very model")
    parser.add_argument(
        "--half", action="store_true", help="store a shipped model's weights as float16"
    )
    parser.add_argument(
        "--inference",
        nargs="+",
        metavar="KEY=VALUE",
        help="set a shipped segmenter's inference settings (values read as JSON)",
    )
    parser.add_argument(
        "--axis-head",
        type=Path,
        metavar="SCANS",
        help="fit an axis head onto a shipped votes segmenter on this scan folder",
    )
    parser.add_argument("--axis-poses", type=int, default=6, help="--axis-head: poses per object")
    parser.add_argument("--axis-epochs", type=int, default=20, help="--axis-head: epochs")
    parser.add_argument("--seed", type=int, default=0, help="--axis-head: the head's seed")
    parser.add_argument("--commit", help="default: the git commit of the folder's checkout")
    parser.add_argument("--preset", default="", help="when the manifest predates recording it")
    parser.add_argument("--store", type=Path, default=STORE)
    args = parser.parse_args()
    if args.programs:
        for program in compile_shipped(args.store):
            print(f"program: {program}")  # noqa: T201
        return
    if args.folder is None:
        parser.error("a model folder, or --programs")
    commit = args.commit or _commit(args.folder)
    shipped = (args.folder / CARD_JSON).is_file() and not (args.folder / MANIFEST).is_file()
    if (args.half or args.inference or args.axis_head) and (
        not shipped or args.evaluation is not None
    ):
        parser.error(
            "--half, --inference and --axis-head take a shipped model's folder and no --evaluation"
        )
    try:
        if args.axis_head:
            target = _add_axis_head(args.folder, args.axis_head, args)
        elif args.half:
            target = halve_shipped(args.folder)
        elif args.inference:
            target = set_inference_shipped(
                args.folder, _settings(args.inference, parser), _inference_settings
            )
        elif shipped and args.evaluation is not None:
            target = recard_shipped(args.folder, args.evaluation)
        else:
            target = ship_model(args.folder, args.evaluation, args.store, commit, args.preset)
    except InputError as err:
        raise SystemExit(f"error: {err}") from None
    print(f"shipped: {target}")  # noqa: T201
    compile_shipped(args.store)


if __name__ == "__main__":
    main()
