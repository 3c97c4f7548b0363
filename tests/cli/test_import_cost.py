"""What `artic infer-hierarchy` (and `segment`, `build-hierarchy`) load before they need
it, and how their process runs (docs/hierarchy.md, "Speed"): the heavy libraries are
imported only by the step that uses them; the process runs its networks on one OpenMP
thread and without passes of the cyclic collector. Checks run in a fresh interpreter
(`sys.modules` of this one holds whatever other tests imported)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import typer
from test_infer_hierarchy import save_models

from artic.artifacts.ply import write_ply
from artic.cli.main import ONE_SCAN_COMMANDS, app
from box_clouds import box_cloud
from fresh_python import in_fresh_python, loaded_after, loaded_code

#: loaded only by the step that uses them: the labeller (torch_geometric), the joint axes
#: and URDF meshes (trimesh, which brings scipy.optimize)
STEP_LIBRARIES = ("torch_geometric", "trimesh", "scipy.optimize")
#: never needed by these commands (hierarchy.png is drawn with Pillow)
OTHER_LIBRARIES = ("open3d", "pybullet", "hydra", "omegaconf", "sympy", "pandas", "matplotlib")


def test_the_cli_entry_point_imports_no_numerical_library() -> None:
    # what `artic ...` imports before it knows which subcommand runs
    names = ("numpy", "torch", "scipy", *STEP_LIBRARIES, *OTHER_LIBRARIES)
    assert loaded_after("import artic.cli.main", names) == []


def test_the_scan_commands_import_the_step_libraries_only_when_a_step_needs_them() -> None:
    # what the segment / build-hierarchy / infer-hierarchy callbacks import before they
    # read the scan and load the models
    names = (*STEP_LIBRARIES, *OTHER_LIBRARIES)
    statement = "import artic.cli.infer_hierarchy, artic.hierarchy.commands"
    assert loaded_after(statement, names) == []


#: the whole command, run by `main` in a fresh interpreter; what it loaded, seen at exit
WHOLE = """
import atexit, json, sys
import artic.cli.main as m
def seen():
    LOADED
    print(json.dumps(loaded))
atexit.register(seen)
sys.argv = ["artic", *ARGV]
m.main()
"""


def test_a_cached_labeller_spares_infer_hierarchy_the_pyg_import(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The labeller runs as its compiled program (artic.hierarchy.compiled) once that is
    cached: the whole command then loads neither torch_geometric nor torch._dynamo
    (seconds of import, docs/hierarchy.md "Speed"), nor matplotlib (hierarchy.png is drawn
    with Pillow)."""
    # a cache of its own: other tests' models have the same bytes, so the same program
    monkeypatch.setenv("ARTIC_CACHE", str(tmp_path / "cache"))
    seg, lab = save_models(tmp_path / "models")
    points, _ = box_cloud(3000)
    scan = tmp_path / "scan.ply"
    write_ply(scan, points)
    argv = ["-q", "infer-hierarchy", str(scan), "--segmenter", str(seg), "--labeller", str(lab)]
    heavy = ("torch_geometric", "torch._dynamo", "matplotlib")
    code = WHOLE.replace("LOADED", loaded_code(heavy).strip())
    first = in_fresh_python(code.replace("ARGV", repr([*argv, "--out", str(tmp_path / "a")])))
    assert "torch_geometric" in first  # type: ignore[operator]  # compiled, into the cache
    again = in_fresh_python(code.replace("ARGV", repr([*argv, "--out", str(tmp_path / "b")])))
    assert again == []
    for name in ("parts.ply", "object.urdf", "hierarchy.png"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


#: `main` with the Typer app replaced by a probe: the collector's state and OMP_NUM_THREADS
#: while the command runs, whether the heap is frozen at exit (seen by an exit handler
#: registered before `main`, so run after its own), the exit code
PROBE = """
import atexit, gc, json, os, sys
import artic.cli.main as m
seen = {}
atexit.register(lambda: print(json.dumps({**seen, "frozen": gc.get_freeze_count() > 0})))
def probe():
    seen.update(collecting=gc.isenabled(), threads=os.environ.get("OMP_NUM_THREADS"))
    sys.exit(3)
m.app = probe
sys.argv = ["artic", *ARGV]
try:
    m.main()
except SystemExit as exit:
    seen["code"] = exit.code
"""


@pytest.mark.parametrize(
    ("argv", "one_scan"),
    [
        (["-q", "infer-hierarchy", "scan.ply", "--out", "x"], True),
        (["segment", "scan.ply"], True),
        (["build-hierarchy", "parts.ply"], True),
        (["-q", "train-segmenter", "debug=tiny"], False),
        (["--version"], False),
    ],
)
def test_a_scan_command_runs_on_one_thread_without_collector_passes(
    argv: list[str], one_scan: bool
) -> None:
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}
    seen = in_fresh_python(PROBE.replace("ARGV", repr(argv)), env)
    assert seen == {
        "collecting": not one_scan,
        "threads": "1" if one_scan else None,
        "code": 3,
        "frozen": one_scan,
    }


def test_a_thread_count_the_user_set_is_kept() -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "2"}
    seen = in_fresh_python(PROBE.replace("ARGV", repr(["infer-hierarchy", "s.ply"])), env)
    assert seen == {"collecting": False, "threads": "2", "code": 3, "frozen": True}


def test_the_one_scan_commands_are_the_scan_commands() -> None:
    assert {"segment", "build-hierarchy", "infer-hierarchy"} == ONE_SCAN_COMMANDS
    root = typer.main.get_command(app)
    ctx = typer.Context(root)
    for name in ONE_SCAN_COMMANDS:
        assert root.get_command(ctx, name) is not None  # type: ignore[attr-defined]


def test_the_command_gives_the_same_bytes_on_one_or_two_threads(tmp_path: Path) -> None:
    # the one-thread default changes no output: run as `artic` runs (in its own process),
    # with OMP_NUM_THREADS=1 (the default) and 2
    seg, lab = save_models(tmp_path / "models")
    points, _ = box_cloud(3000)
    scan = tmp_path / "scan.ply"
    write_ply(scan, points)
    outs = [tmp_path / "threads1", tmp_path / "threads2"]
    for threads, out in zip(("1", "2"), outs, strict=True):
        command = [sys.executable, "-m", "artic", "-q", "infer-hierarchy", str(scan)]
        command += ["--out", str(out), "--segmenter", str(seg), "--labeller", str(lab)]
        env = {**os.environ, "OMP_NUM_THREADS": threads}
        done = subprocess.run(command, env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    documents = [json.loads((o / "hierarchy.json").read_text()) for o in outs]
    for document in documents:
        del document["timings_s"]
    assert documents[0] == documents[1]
    assert documents[0]["num_parts"] > 1  # a tree with joints, not one part
    for name in ("parts.ply", "object.urdf", "hierarchy.png"):
        assert (outs[0] / name).read_bytes() == (outs[1] / name).read_bytes(), name
