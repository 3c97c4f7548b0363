"""ScanDataset (render-scan folders) and ObjectDataset's Chapter 4 readers."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from artic.artifacts.object_dataset import ObjectDataset
from artic.artifacts.scan_dataset import ScanDataset, split_train_objects
from artic.errors import InputError
from artic.objects.spec import ObjectSpec
from artic.objects.structures import StructureSpec
from tiny_scans import TinyScans, tiny_hierarchy_scans


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> TinyScans:
    return tiny_hierarchy_scans(tmp_path_factory)


def test_rows_select_clouds_and_trees(tiny: TinyScans) -> None:
    ds = ScanDataset.open(tiny.scans)
    assert ds.category == "storage_furniture"
    assert len(ds.rows) == 6 * 2 * 2  # objects x poses x (clean, noisy)
    assert ds.object_ids() == list(range(6))
    assert ds.object_ids("test") == [2, 5] and ds.object_ids("train") == [0, 1, 3, 4]
    noisy = ds.select("train", ("noisy",), [0, 1])
    assert [(r.object_id, r.pose) for r in noisy] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert all(r.kind == "noisy" and r.split == "train" for r in noisy)
    assert not ds.select("train", objects=[2])  # a test object has no training rows
    cloud = ds.cloud(noisy[0])
    assert cloud.points.shape == (noisy[0].points, 3) and cloud.points.dtype == np.float32
    assert cloud.part_id is not None and cloud.motion_type is not None
    tree = ds.tree(0)
    assert cloud.part_id.max() < tree.num_parts
    motion = np.asarray(tree.motion_types)
    assert np.array_equal(motion[cloud.part_id], cloud.motion_type), "labels agree with tree"


def test_object_dataset_reads_structure_specs_trees_and_poses(tiny: TinyScans) -> None:
    objects = ObjectDataset.open(tiny.objects)
    spec = objects.spec(0)
    assert isinstance(spec, StructureSpec) and not isinstance(spec, ObjectSpec)
    assert spec.category == "storage_furniture"
    with pytest.raises(InputError, match="varying kinematic tree"):
        objects.template_spec(0)
    tree = objects.tree(3).to_kinematic_tree()
    scanned = ScanDataset.open(tiny.scans).tree(3)
    assert (tree.edges, tree.motion_types) == (scanned.edges, scanned.motion_types)
    poses = objects.poses(3)
    assert poses.array().shape == (18, objects.tree(3).dof)


def test_object_dataset_of_appendix_a_has_no_tree(tiny_objects: Path) -> None:
    objects = ObjectDataset.open(tiny_objects)
    assert isinstance(objects.spec(0), ObjectSpec)
    assert objects.template_spec(0) == objects.spec(0)
    with pytest.raises(InputError, match="generate it with dataset=hierarchy"):
        objects.tree(0)
    with pytest.raises(InputError, match=r"poses\.json"):
        objects.poses(0)


def test_split_train_objects_is_by_object_and_disjoint() -> None:
    split = split_train_objects([7, 1, 3, 4, 9, 3], 2)
    assert split.train == [1, 4, 9] and split.val == [3, 7]
    assert split_train_objects([1], 10).val == []
    with pytest.raises(ValueError, match="val_every"):
        split_train_objects([1, 2], 1)


def test_wrong_folders_are_refused_by_name(tiny: TinyScans, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="expected a 'render-scan' output"):
        ScanDataset.open(tiny.objects)
    with pytest.raises(InputError, match=r"scans: .* holds storage_furniture scans, not lamp"):
        ScanDataset.open_category(tiny.scans, "lamp")
    copy = tmp_path / "scans"
    shutil.copytree(tiny.scans, copy)
    ds = ScanDataset.open(copy)
    row = ds.rows[0]
    (copy / row.file).write_bytes(b"ply\n")
    with pytest.raises(InputError, match="corrupted"):
        ds.cloud(row)
    tree = copy / "trees" / "000000.json"
    tree.write_text(json.dumps({"num_parts": 2}))
    with pytest.raises(InputError, match=r"000000\.json"):
        ds.tree(0)
