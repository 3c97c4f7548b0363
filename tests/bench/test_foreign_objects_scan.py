"""`artic render-scan` on objects another generator wrote in generate-dataset's layout:
their spec's category is none of artic's, so they are built from their object.urdf and
meshes (`render.scan_objects.dataset_object`), and scan to the same bytes as through the
generator's own registered builder (bench/independent_objects.py's render-scan mode)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from artic.artifacts.scan_dataset import ScanDataset
from artic.objects.structures import STRUCTURES
from cli_runner import run_cli

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "independent_objects.py"


def _script(*args: str) -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr


def test_a_foreign_dataset_scans_from_its_urdf_as_from_its_builder(tmp_path: Path) -> None:
    objects = tmp_path / "objects"
    _script(
        "--category", "storage_furniture", "--objects", "1", "--seed", "3", "--out", str(objects)
    )
    assert "independent_storage_furniture" not in STRUCTURES  # this process cannot build it
    scan = ("render.configurations=1", "render.clean_points=2000", "render.fusion.max_points=2000")
    code, _, err = run_cli("render-scan", f"dataset={objects}", *scan, f"out={tmp_path / 'urdf'}")
    assert code == 0, err
    _script("render-scan", f"dataset={objects}", *scan, f"out={tmp_path / 'builder'}")
    by_urdf = ScanDataset.open(tmp_path / "urdf")
    rows = by_urdf.select("test", ("clean", "noisy"))
    assert len(rows) == 2
    for row in rows:
        assert (tmp_path / "urdf" / row.file).read_bytes() == (
            tmp_path / "builder" / row.file
        ).read_bytes()
    tree = "trees/000000.json"
    assert (tmp_path / "urdf" / tree).read_bytes() == (tmp_path / "builder" / tree).read_bytes()
