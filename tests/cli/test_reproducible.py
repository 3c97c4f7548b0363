"""Same command, same bytes: reruns, runtime settings, training threads, kernel pins.

The guarantees of docs/architecture.md ("Guarantees") that concern the numbers: runtime
settings never change a data file; a rerun that reproduces the data keeps the content
hash (timing files are out of it); the thread count of training is part of its config;
every artic process pins the numerical libraries' kernels.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from artic.artifacts.manifest import TIMING_FILES, read_manifest
from artic.reproducibility import PINNED, cpu_supports_pins, numerics_record, pin_numerics
from cli_runner import run_cli


def data_bytes(folder: Path) -> dict[str, bytes]:
    """Every data file of an output folder: not the manifest, log or timing files."""
    skip = {"manifest.json", "artic.log", *TIMING_FILES}
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in skip
    }


MDN = ("train-mdn", "debug=tiny", "category=microwave")


@pytest.fixture(scope="module")
def mdn(tiny_depth: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("repro") / "mdn"
    code, _, err = run_cli(*MDN, f"depth={tiny_depth}", f"out={out}")
    assert code == 0, err
    return out


def test_rerun_of_training_keeps_the_content_hash(mdn, tiny_depth, tmp_path):
    out = tmp_path / "again"
    code, _, err = run_cli(*MDN, f"depth={tiny_depth}", f"out={out}")
    assert code == 0, err
    first, again = read_manifest(mdn), read_manifest(out)
    assert "timings.csv" in first.outputs and "seconds" in (mdn / "timings.csv").read_text()
    assert "seconds" not in (mdn / "metrics.csv").read_text().splitlines()[0]
    assert data_bytes(mdn) == data_bytes(out)
    assert first.content_hash == again.content_hash  # whatever the epochs' wall clock was


def test_training_threads_are_part_of_the_config(mdn, tiny_depth, tmp_path):
    depth = f"depth={tiny_depth}"
    code, _, err = run_cli(*MDN, depth, f"out={tmp_path / 'r'}", "runtime.threads=1")
    assert code == 2 and "runtime" in err and "train.threads" in err, err
    assert len(err.strip().splitlines()) == 1
    code, _, err = run_cli(*MDN, depth, f"out={tmp_path / 'one'}", "train.threads=1")
    assert code == 0, err
    one, two = read_manifest(tmp_path / "one"), read_manifest(mdn)
    assert one.config["train"]["threads"] == 1 and two.config["train"]["threads"] == 2
    assert one.config_hash != two.config_hash


def test_evaluate_mdn_is_the_same_with_one_or_two_threads(mdn, tiny_depth, tmp_path):
    outs = []
    for threads in (1, 2):
        out = tmp_path / f"eval{threads}"
        code, _, err = run_cli(
            "evaluate", "mdn", "debug=tiny", "category=microwave", f"model={mdn}",
            f"depth={tiny_depth}", f"out={out}", f"runtime.threads={threads}",
        )  # fmt: skip
        assert code == 0, err
        outs.append(out)
    assert "summary.csv" in data_bytes(outs[0])
    assert data_bytes(outs[0]) == data_bytes(outs[1])
    assert read_manifest(outs[0]).content_hash == read_manifest(outs[1]).content_hash


def test_pin_numerics_sets_what_is_unset_and_keeps_the_users_values():
    env = {"MKL_CBWR": "COMPATIBLE"}
    applies = pin_numerics(env)
    assert applies == cpu_supports_pins()
    if applies:
        assert env == PINNED | {"MKL_CBWR": "COMPATIBLE"}
        assert numerics_record(env).startswith("MKL_CBWR=COMPATIBLE ATEN_CPU_CAPABILITY=avx2")
    else:
        assert env == {"MKL_CBWR": "COMPATIBLE"}


@pytest.mark.skipif(not cpu_supports_pins(), reason="the pins apply to x86-64 CPUs with AVX2")
def test_artic_processes_run_with_the_pinned_kernels(tmp_path):
    """A real `artic` process: the pins are in force before NumPy loads (OpenBLAS reports
    the pinned kernel) and the manifest records them; a user's own value is kept."""
    # the machine's own OPENBLAS_CORETYPE, where it sets one, is kept (as artic keeps it)
    kept = {k: v for k, v in os.environ.items() if k == "OPENBLAS_CORETYPE"}
    env = {k: v for k, v in os.environ.items() if k not in PINNED} | kept
    probe = (
        "import sys; from artic.cli import main as m; m.app = lambda: None; m.main(); "
        "import numpy, threadpoolctl, json; "
        "print(json.dumps([i.get('architecture') for i in threadpoolctl.threadpool_info() "
        "if i['internal_api'] == 'openblas']))"
    )
    ran = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    want = (kept.get("OPENBLAS_CORETYPE") or PINNED["OPENBLAS_CORETYPE"]).lower()
    assert {a.lower() for a in json.loads(ran.stdout)} == {want}
    out = tmp_path / "objects"
    args = [sys.executable, "-m", "artic", "-q", "generate-dataset", "debug=tiny", f"out={out}"]
    ran = subprocess.run(args, env=env | {"MKL_CBWR": "COMPATIBLE"}, capture_output=True)
    assert ran.returncode == 0, ran.stderr
    expected = numerics_record(PINNED | kept | {"MKL_CBWR": "COMPATIBLE"})
    assert read_manifest(out).versions["numerics"] == expected
