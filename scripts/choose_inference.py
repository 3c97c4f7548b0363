"""Choose a trained segmenter's inference settings on whole validation scans, for maintainers.

    python scripts/choose_inference.py models/segmenter/office_chair \
        --scans artifacts/scans/office_chair --out choice.json

runs `artic.hierarchy.fit_segmenter.choose_inference` (votes head): the passes, minimum
part size, per-motion-type cluster radii and mode-seeking bandwidth whose mean of clean
and noisy mAP@0.5 is the best on the model's own validation objects (their ids are in the
model file), each scan's every point labelled as `artic evaluate hierarchy` labels it.
`--scans` must be the scan folder the model was trained on (its content hash is checked
against the model's). Prints the chosen settings, the `scripts/ship_model.py --inference`
line that sets them on a shipped model, and writes every tried setting's score to --out.
docs/hierarchy.md, "Inference settings on whole scans", says why and what it gave.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import torch

from artic.artifacts.scan_dataset import ScanDataset
from artic.errors import InputError
from artic.hierarchy.fit_segmenter import InferenceSearch, choose_inference, validation_scans
from artic.hierarchy.models import load_segmenter

FIELDS = (
    "moving_together", "passes", "modes_per_pass", "min_points", "cluster_radius",
    "mode_bandwidth",
)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=Path, help="a segmenter's folder (model.pt)")
    parser.add_argument("--scans", type=Path, required=True, help="its training scan folder")
    parser.add_argument("--max-poses", type=int, default=4, help="poses per validation object")
    parser.add_argument("--passes", type=int, nargs="*", default=[1, 2, 3])
    parser.add_argument("--min-points", type=int, nargs="*", default=[2, 3, 4, 5, 6, 8])
    parser.add_argument(
        "--radii", type=float, nargs="*", default=[0.03, 0.05, 0.08, 0.12, 0.16, 0.2]
    )
    parser.add_argument("--bandwidths", type=float, nargs="*", default=[0.0, 0.03, 0.05, 0.08])
    parser.add_argument(
        "--moving-together",
        choices=["false", "true"],
        nargs="*",
        default=["false", "true"],
        help="inference.moving_together candidates (the first step of the search)",
    )
    parser.add_argument(
        "--modes-per-pass",
        choices=["false", "true"],
        nargs="*",
        default=[],
        help="inference.modes_per_pass candidates (after the passes; default: kept)",
    )
    parser.add_argument("--out", type=Path, help="every tried setting's score (JSON)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    try:
        loaded = load_segmenter(args.folder / "model.pt")
        ds = ScanDataset.open_category(args.scans, loaded.category)
        trained_on = loaded.meta.get("data", {}).get("content_hash")
        if trained_on is not None and trained_on != ds.manifest.content_hash:
            print(  # noqa: T201
                f"note: {args.scans} has content hash {ds.manifest.content_hash[:16]}, the "
                f"model was trained on {trained_on[:16]} (same recipe on another machine?)"
            )
        objects = loaded.meta.get("val_objects")
        if not objects:
            raise InputError(f"{args.folder / 'model.pt'}: records no validation objects")
        scans = validation_scans(ds, objects, ("clean", "noisy"), args.max_poses)
    except InputError as err:
        raise SystemExit(f"error: {err}") from None
    search = InferenceSearch(
        tuple(args.passes),
        tuple(args.min_points),
        tuple(args.radii),
        tuple(args.bandwidths),
        tuple(v == "true" for v in args.moving_together),
        tuple(v == "true" for v in args.modes_per_pass),
    )
    chosen, scores = choose_inference(loaded.model, scans, loaded.inference, search)
    saved = next(iter(scores.values()), float("nan"))  # the first scored: the saved settings
    best = max(scores.values(), default=float("nan"))  # the search only moves up: the chosen
    changed = {
        f: getattr(chosen, f) for f in FIELDS if getattr(chosen, f) != getattr(loaded.inference, f)
    }
    print(f"{len(scans)} validation scans; mAP (mean of clean and noisy): saved settings "  # noqa: T201
          f"{saved:.4f}, chosen {best:.4f}")  # fmt: skip
    pairs = " ".join(
        f"{k}={json.dumps(list(v) if isinstance(v, tuple) else v, separators=(',', ':'))}"
        for k, v in changed.items()
    )
    print(f"chosen: {pairs or 'the saved settings'}")  # noqa: T201
    if changed:
        print(f"python scripts/ship_model.py {args.folder} --inference {pairs}")  # noqa: T201
    if args.out is not None:
        args.out.write_text(json.dumps({"scans": len(scans), "scores": scores}, indent=1) + "\n")


if __name__ == "__main__":
    main()
