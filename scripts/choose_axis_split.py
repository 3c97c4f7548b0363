"""Choose a segmenter's axis cut (`inference.axis_smooth`, `axis_share`) on whole validation
scans, for maintainers.

    python scripts/choose_axis_split.py models/segmenter/office_chair \
        --labeller models/hierarchy/office_chair --scans artifacts/scans/office_chair

scores every pair of --smooth x --share candidates (and the saved settings) on the model's
own validation objects (their ids are in the model file; the first --max-poses poses,
clean and noisy) as `artic evaluate hierarchy` scores a scan: mAP@0.5 of the segmenter's
parts and the Tree F1 of the graph network's tree on them. A cut part is a node the tree
must place, so the cut that raises mAP most can lower the Tree F1: the pair chosen is the
one of the highest mean (clean, noisy) mAP among those whose mean Tree F1 is not below the
saved settings' (docs/hierarchy.md, "One axis per part"). Prints every pair's figures,
the choice and the `scripts/ship_model.py --inference` line that sets it; --out writes
them as JSON. The segmenter must have an axis head and `inference.axis_split` on.
"""

from __future__ import annotations

import argparse
import itertools
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from artic.artifacts.scan_dataset import KINDS, ScanDataset
from artic.errors import InputError
from artic.evaluation.hierarchy_report import table_rows
from artic.hierarchy.config import HierarchyEvaluateConfig
from artic.hierarchy.evaluate import evaluate_rows, evaluation_config
from artic.hierarchy.models import load_labeller, load_segmenter


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=Path, help="a segmenter's folder (model.pt)")
    parser.add_argument("--labeller", type=Path, required=True, help="a graph network's folder")
    parser.add_argument("--scans", type=Path, required=True, help="its training scan folder")
    parser.add_argument("--max-poses", type=int, default=4, help="poses per validation object")
    parser.add_argument("--smooth", type=int, nargs="*", default=[0, 4, 6, 8])
    parser.add_argument("--share", type=float, nargs="*", default=[0.0, 0.15, 0.25])
    parser.add_argument("--out", type=Path, help="every pair's figures (JSON)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    try:
        seg = load_segmenter(args.folder / "model.pt")
        lab = load_labeller(args.labeller / "model.pt", seg.category)
        if not (seg.model.config.axis_head and seg.inference.axis_split):
            raise InputError(f"{args.folder / 'model.pt'}: no axis head or axis_split off")
        ds = ScanDataset.open_category(args.scans, seg.category)
        objects = seg.meta.get("val_objects")
        if not objects:
            raise InputError(f"{args.folder / 'model.pt'}: records no validation objects")
    except InputError as err:
        raise SystemExit(f"error: {err}") from None
    rows = [r for r in ds.select("train", KINDS, list(objects)) if r.pose < args.max_poses]
    opts = HierarchyEvaluateConfig()
    base = evaluation_config(seg, lab, opts)  # as `artic evaluate hierarchy` runs the models
    saved = (seg.inference.axis_smooth, seg.inference.axis_share)
    pairs = [saved, *(p for p in itertools.product(args.smooth, args.share) if p != saved)]
    figures: dict[str, dict[str, float]] = {}
    for smooth, share in pairs:
        update = {"axis_smooth": smooth, "axis_share": share}
        cfg = replace(base, segmentation=base.segmentation.model_copy(update=update))
        records, _ = evaluate_rows(ds, rows, seg.model, lab.model, cfg, opts, 0)
        pred = [r for r in table_rows(records, KINDS) if r["segmentation"] == "pred"]
        scores = {f"{r['kind']}_map": float(r["map"]) for r in pred}
        scores |= {f"{r['kind']}_tree_f1": float(r["tree_f1"]) for r in pred}
        scores["map"] = float(np.mean([scores[f"{k}_map"] for k in KINDS]))
        scores["tree_f1"] = float(np.mean([scores[f"{k}_tree_f1"] for k in KINDS]))
        key = f"axis_smooth={smooth};axis_share={share:g}"
        figures[key] = scores
        print(key, "  ".join(f"{k} {v:.4f}" for k, v in scores.items()), flush=True)  # noqa: T201
    first = next(iter(figures.values()))
    allowed = {k: v for k, v in figures.items() if v["tree_f1"] >= first["tree_f1"]}
    chosen = max(allowed, key=lambda k: allowed[k]["map"])  # ties: the first (saved)
    print(f"{len(rows)} validation scans; chosen: {chosen}")  # noqa: T201
    if chosen != next(iter(figures)):
        settings = chosen.replace(";", " ")
        print(f"python scripts/ship_model.py {args.folder} --inference {settings}")  # noqa: T201
    if args.out is not None:
        text = json.dumps({"scans": len(rows), "chosen": chosen, "figures": figures}, indent=1)
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
