"""`artic train-segmenter` end to end on tiny scans made by the real stages."""

from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from artic.artifacts.scan_dataset import ScanDataset
from artic.hierarchy import fit_segmenter
from artic.hierarchy.models import load_segmenter
from artic.hierarchy.segmentation import segment
from cli_runner import run_cli
from tiny_scans import TinyScans, tiny_hierarchy_scans

ARGS = ("train-segmenter", "debug=tiny", "category=storage_furniture")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> TinyScans:
    return tiny_hierarchy_scans(tmp_path_factory)


@pytest.fixture(scope="module")
def trained(tiny: TinyScans, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("segmenter") / "storage_furniture"
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={out}")
    assert code == 0, err
    return out


def _weights(folder: Path) -> dict[str, torch.Tensor]:
    return load_segmenter(folder / "model.pt").model.state_dict()


def _same(a: Path, b: Path) -> bool:
    x, y = _weights(a), _weights(b)
    return x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x)


def test_writes_model_metrics_and_card(trained: Path, tiny: TinyScans) -> None:
    for name in ("model.pt", "metrics.csv", "model.json", "model_card.md", "manifest.json"):
        assert (trained / name).is_file(), name
    rows = (trained / "metrics.csv").read_text().splitlines()
    assert rows[0].startswith("epoch,train_loss,") and len(rows) == 3
    loaded = load_segmenter(trained / "model.pt", "storage_furniture")
    assert loaded.inference.n_points == 128 and loaded.model.config.n_masks == 24
    test_objects = set(ScanDataset.open(tiny.scans).object_ids("test"))
    used = set(loaded.meta["train_objects"]) | set(loaded.meta["val_objects"])
    assert used == {0, 1, 3, 4} and not used & test_objects, "test split never used"
    assert not set(loaded.meta["train_objects"]) & set(loaded.meta["val_objects"])
    info = json.loads((trained / "model.json").read_text())
    assert info["train_clouds"] == 2 * 2 * 2 and info["val_clouds"] == 8  # 2 poses x 2 kinds
    assert 0.0 <= info["val_map_clean"] <= 1.0 and 0.0 <= info["val_map_noisy"] <= 1.0
    assert "validation mAP@0.5" in (trained / "model_card.md").read_text()
    ds = ScanDataset.open(tiny.scans)
    cloud = ds.cloud(ds.select("test", ("noisy",))[0])
    result = segment(loaded.model, cloud.points, loaded.inference)
    assert result.part_id.shape == (len(cloud.points),)


def test_same_seed_same_weights(trained: Path, tiny: TinyScans, tmp_path: Path) -> None:
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={tmp_path / 'again'}")
    assert code == 0, err
    assert _same(trained, tmp_path / "again")


def test_interrupted_training_resumes_to_the_same_weights(
    trained: Path, tiny: TinyScans, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    original = fit_segmenter.train_epoch
    calls: list[int] = []

    def interrupt_second(*args: Any, **kwargs: Any) -> tuple[float, float]:
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(fit_segmenter, "train_epoch", interrupt_second)
    out = tmp_path / "resumed"
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={out}")
    assert code == 130 and "resume" in err and not out.exists()
    monkeypatch.setattr(fit_segmenter, "train_epoch", original)
    code, _, err = run_cli(*ARGS, f"scans={tiny.scans}", f"out={out}")
    assert code == 0, err
    assert _same(trained, out), "resumed = uninterrupted"
    assert len((out / "metrics.csv").read_text().splitlines()) == 3


def test_bad_inputs_exit_2(tiny: TinyScans, tmp_path: Path) -> None:
    depth_like = tmp_path / "depth"
    shutil.copytree(tiny.scans, depth_like)
    manifest = json.loads((depth_like / "manifest.json").read_text())
    (depth_like / "manifest.json").write_text(json.dumps(manifest | {"stage": "render-depth"}))
    cases = [
        ((f"scans={depth_like}",), "expected a 'render-scan' output"),
        ((f"scans={tiny.objects}",), "expected a 'render-scan' output"),
        ((f"scans={tiny.scans}", "category=lamp"), "holds storage_furniture scans, not lamp"),
        ((f"scans={tiny.scans}", "category=no_such_category"), "no_such_category"),
        ((f"scans={tiny.scans}", "train.lr=-1"), "train.lr"),
        ((f"scans={tiny.scans}", "data.val_every=10"), "scan more objects"),
        ((f"scans={tiny.scans}", "inference.mirror_y=true"), "inference.mirror_y"),
        ((f"scans={tiny.scans}", "inference.passes=2"), "inference.passes"),
        ((f"scans={tiny.scans}", "inference.passes=0"), "inference.passes"),
    ]
    for extra, message in cases:
        code, _, err = run_cli(*ARGS, *extra, f"out={tmp_path / 'x'}")
        assert code == 2, (extra, err)
        assert message in err, (extra, err)
        assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x").exists()


def test_prepared_clouds_are_cached_for_resume(tiny: TinyScans, tmp_path: Path) -> None:
    from artic.cli.stage_runner import resolved_config
    from artic.cli.train_segmenter import STAGE
    from artic.config.compose import validate
    from artic.hierarchy.fit_segmenter import load_clouds

    raw = resolved_config(STAGE, ["debug=tiny", f"scans={tiny.scans}", f"out={tmp_path}"])
    cfg = validate(STAGE.schema, raw)
    ds = ScanDataset.open(tiny.scans)
    n_points, n_masks = cfg.inference.n_points, cfg.model.n_masks
    data, skipped = load_clouds(ds, [0, 3], cfg.data, n_points, n_masks, cfg.seed)
    assert skipped == 0 and len(data) == 8
    assert data.points.shape == (8, 128, 3) and data.noisy.sum() == 4
    assert set(np.unique(data.object_id)) == {0, 3}


@pytest.mark.parametrize("experiment", ["ch4_cpu", "ch4_paper"])
def test_experiments_compose(experiment: str) -> None:
    from artic.cli.stage_runner import resolved_config
    from artic.cli.train_segmenter import STAGE
    from artic.config.compose import validate

    cfg = validate(STAGE.schema, resolved_config(STAGE, [f"experiment={experiment}"]))
    network = cfg.model.network()
    assert network.n_masks == 24 and cfg.data.kinds == ("clean", "noisy")
    assert cfg.train.lr == (1e-4 if experiment == "ch4_paper" else 1e-3)


def test_votes_head_trains_chooses_its_radius_and_segments(tiny: TinyScans, tmp_path: Path) -> None:
    """`model.head=votes`: the clustering radius is chosen on the validation clouds and
    saved with the model, which `segment` then uses."""
    out = tmp_path / "votes"
    radii = "train.cluster_radii=[0.05,0.2]"
    code, _, err = run_cli(*ARGS, "model.head=votes", radii, f"scans={tiny.scans}", f"out={out}")
    assert code == 0, err
    loaded = load_segmenter(out / "model.pt", "storage_furniture")
    assert loaded.model.config.head == "votes"
    scores = loaded.meta["cluster_radius_val_map"]  # "r_static,r_rotating,...": mAP
    assert {"0.05,0.05,0.05,0.05", "0.2,0.2,0.2,0.2"} <= set(scores) and len(scores) <= 2 + 4
    chosen = ",".join(f"{r:g}" for r in loaded.inference.cluster_radius)
    assert scores[chosen] == max(scores.values())
    rows = (out / "metrics.csv").read_text().splitlines()
    assert "val_offset_error" in rows[0] and "matched_iou" not in rows[0]
    assert "votes head" in (out / "model_card.md").read_text()
    ds = ScanDataset.open(tiny.scans)
    cloud = ds.cloud(ds.select("test", ("noisy",))[0])
    result = segment(loaded.model, cloud.points, loaded.inference)
    assert result.part_id.shape == (len(cloud.points),)
    assert len(result.part_confidence) == result.part_id.max() + 1


def test_votes_head_trains_with_an_axis_head(tiny: TinyScans, tmp_path: Path) -> None:
    """`model.axis_head=true`: the axis head trains with the rest (its loss in the total:
    `votes.vote_loss`), the model file keeps it and `inference.axis_split`, the model card
    names it, and `segment` reads it."""
    out = tmp_path / "axis"
    code, _, err = run_cli(
        *ARGS, "model.head=votes", "model.axis_head=true", "inference.axis_split=true",
        "train.cluster_radii=[0.2]", f"scans={tiny.scans}", f"out={out}",
    )  # fmt: skip
    assert code == 0, err
    loaded = load_segmenter(out / "model.pt", "storage_furniture")
    assert loaded.model.config.axis_head and loaded.inference.axis_split
    assert "an axis head" in (out / "model_card.md").read_text()
    ds = ScanDataset.open(tiny.scans)
    cloud = ds.cloud(ds.select("test", ("noisy",))[0])
    result = segment(loaded.model, cloud.points, loaded.inference)
    assert result.part_id.shape == (len(cloud.points),)


def test_an_axis_head_fitted_onto_a_shipped_segmenter(tiny: TinyScans, tmp_path: Path) -> None:
    """`scripts/ship_model.py --axis-head`'s pieces (`axis_head_payload` through
    `transform_shipped`) on a copy of the shipped storage-furniture segmenter: the head is
    added and axis_split turned on, every other weight and setting keeps its bytes, the
    card records the change and drops the figures measured on the old file."""
    from artic.artifacts.model_store import read_card, shipped_input, transform_shipped
    from artic.hierarchy.config import CloudDataConfig

    store = Path(__file__).resolve().parents[2] / "models"
    folder = tmp_path / "segmenter"
    shutil.copytree(store / "segmenter" / "storage_furniture", folder)
    before, old = read_card(folder), load_segmenter(folder / "model.pt")
    fits = []

    def transform(payload: dict[str, Any]) -> dict[str, Any]:
        data = CloudDataConfig(max_poses=1, val_every=2)
        new, fit = fit_segmenter.axis_head_payload(payload, tiny.scans, data, 2, 0)
        fits.append(fit)
        return new

    assert transform_shipped(folder, transform, "an axis head") == folder
    card, new = read_card(folder), load_segmenter(folder / "model.pt")
    assert new.model.config.axis_head and not old.model.config.axis_head
    assert new.inference == old.inference.model_copy(update={"axis_split": True})
    grown = new.model.state_dict()
    for name, value in old.model.state_dict().items():
        assert torch.equal(grown[name], value), name
    assert {k for k in grown if k not in old.model.state_dict()} and len(fits[0].losses) == 2
    saved = torch.load(folder / "model.pt", weights_only=True)["state_dict"]
    assert saved["axis.0.layers.1.num_batches_tracked"].dtype == torch.int64
    assert card.changes == ("an axis head",) and card.figures == {} and before.figures
    assert shipped_input(folder, card.stage) is not None  # the card matches the new bytes
    assert "- after training: an axis head" in (folder / "model_card.md").read_text()


def test_votes_head_chooses_passes_and_part_size_on_whole_scans(
    tiny: TinyScans, tmp_path: Path
) -> None:
    """`train.select_passes` / `select_min_points` / `select_moving_together`: after the
    radius search on the prepared clouds, `choose_inference` on the whole validation scans;
    every tried setting's score is saved with the model, the saved settings are the best of
    them, and the card says so."""
    out = tmp_path / "whole"
    code, _, err = run_cli(
        *ARGS, "model.head=votes", "train.cluster_radii=[0.05,0.2]", "train.select_passes=[1,2]",
        "train.select_min_points=[2,8]", "train.select_moving_together=[true]",
        "train.select_poses=1", f"scans={tiny.scans}", f"out={out}",
    )  # fmt: skip
    assert code == 0, err
    loaded = load_segmenter(out / "model.pt", "storage_furniture")
    scores = loaded.meta["whole_scan_val_map"]  # "passes=..;min_points=..;radius=..;h=..": mAP
    s = loaded.inference
    radius = ",".join(f"{r:g}" for r in s.cluster_radius)
    chosen = f"passes={s.passes};min_points={s.min_points};radius={radius};h={s.mode_bandwidth:g}"
    chosen += ";moving_together" if s.moving_together else ""
    assert scores[chosen] == max(scores.values())
    assert {k.split(";")[0] for k in scores} == {"passes=1", "passes=2"}
    # the moving types together or apart was the search's first step; the card names it
    assert {k.endswith(";moving_together") for k in scores} == {False, True}
    card = (out / "model_card.md").read_text()
    assert ("the moving types' votes clustered together" in card) == s.moving_together
    assert "on whole validation scans" in (out / "model_card.md").read_text()


def test_votes_head_static_part_auto_and_mode_bandwidth_chosen(
    tiny: TinyScans, tmp_path: Path
) -> None:
    """`model.static_part=auto` on storage furniture (one static part per cloud) trains a
    "one" model; the bandwidth is chosen with the radii, every setting scored once, the
    chosen one the best, and the model card says so; `model.offset_weight=parts` is saved
    with the network and named in the card."""
    out = tmp_path / "votes"
    code, _, err = run_cli(
        *ARGS, "model.head=votes", "model.static_part=auto", "train.cluster_radii=[0.05,0.2]",
        "train.mode_bandwidths=[0,0.05]", "model.offset_weight=parts", f"scans={tiny.scans}",
        f"out={out}",
    )  # fmt: skip
    assert code == 0, err
    loaded = load_segmenter(out / "model.pt", "storage_furniture")
    assert loaded.model.config.static_part == "one"
    assert loaded.model.config.offset_weight == "parts"
    assert "offsets learnt part by part" in (out / "model_card.md").read_text()
    scores = loaded.meta["cluster_radius_val_map"]  # "r_static,...;h=bandwidth": mAP
    assert {k.split(";")[1] for k in scores} == {"h=0", "h=0.05"}
    # the static radius is not searched when static points are one part
    assert len(scores) <= 2 * (2 + 3 * 2)
    radii = ",".join(f"{r:g}" for r in loaded.inference.cluster_radius)
    chosen = f"{radii};h={loaded.inference.mode_bandwidth:g}"
    assert scores[chosen] == max(scores.values())
    assert "every static point one part" in (out / "model_card.md").read_text()
    # the search reports its progress: 2 bandwidths x (2 radii + 3 types x (kept + 2) + best)
    assert "train-segmenter: cluster radius: 24/24 settings" in err
    assert f"train-segmenter: cluster radius {radii}, bandwidth" in err


def test_cosine_schedule_sets_the_rate_of_every_step(
    tiny: TinyScans, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    rates: list[float] = []
    original = fit_segmenter.train_step

    def record(model: Any, optimizer: torch.optim.Optimizer, *args: Any) -> Any:
        rates.append(float(optimizer.param_groups[0]["lr"]))
        return original(model, optimizer, *args)

    monkeypatch.setattr(fit_segmenter, "train_step", record)
    extra = ("train.schedule=cosine", "train.lr=0.001", "train.min_lr_ratio=0.1")
    code, _, err = run_cli(*ARGS, *extra, f"scans={tiny.scans}", f"out={tmp_path / 'cos'}")
    assert code == 0, err
    assert len(rates) >= 4 and rates[0] == pytest.approx(1e-3)
    assert all(a > b for a, b in itertools.pairwise(rates)), rates
    assert rates[-1] > 1e-4, "the last step is still above the floor (it is reached at the end)"
