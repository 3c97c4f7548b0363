"""The stage registry (src/artic/cli/registry.py) and the commands generated from it."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest
import typer
from test_render_scan import SMALL as RENDER_SCAN_SMALL

import artic.cli
from artic.artifacts.manifest import read_manifest
from artic.cli.main import _options_help, app
from artic.cli.registry import RegistryError, read_declaration, resolve, stage_entries
from artic.cli.stage_runner import Stage
from cli_runner import run_cli

SMALL = [o for o in RENDER_SCAN_SMALL if o != "render=scan"]  # render-scan presets it


def test_the_registry_reads_what_the_stage_modules_define():
    # every module of artic.cli with a STAGE is registered, with the fields it defines
    entries = stage_entries()
    defined = {}
    for info in pkgutil.iter_modules(artic.cli.__path__):
        module = importlib.import_module(f"artic.cli.{info.name}")
        stage = getattr(module, "STAGE", None)
        if isinstance(stage, Stage):
            defined[stage.name] = (module.__name__, stage)
    assert set(defined) == set(entries)
    for name, (module, stage) in defined.items():
        entry = entries[name]
        assert entry.module == module
        assert entry.help == stage.help and stage.help, name
        assert entry.command == tuple((stage.command or stage.name).split())
        assert entry.task_option == stage.task_option
        assert entry.preset == stage.preset
        assert entry.alias == tuple(stage.alias.split())
        assert entry.options == stage.options
        assert entry.inputs == stage.inputs
        for upstream in stage.inputs.values():
            assert upstream in entries, f"{name} reads an output of unknown stage {upstream}"


def test_every_registered_stage_has_its_command():
    root = typer.main.get_command(app)
    ctx = typer.Context(root)
    for entry in stage_entries().values():
        cmd = root
        for word in entry.command:
            cmd = cmd.get_command(ctx, word)  # type: ignore[attr-defined]
            assert cmd is not None, f"no command artic {' '.join(entry.command)}"
        assert cmd.help == inspect.cleandoc(entry.help) + _options_help(entry.options)
        options = {o for p in cmd.params for o in getattr(p, "opts", [])}
        assert {"--cfg", "--force"} <= options
        assert ("--task" in options) == entry.task_option, entry.name
    # the commands not generated from the registry
    for name in ("predict", "segment", "build-hierarchy", "infer-hierarchy", "pipeline"):
        assert root.get_command(ctx, name) is not None  # type: ignore[attr-defined]
    assert resolve("render-depth", ["render=scan"]).name == "render-scan"
    assert resolve("render-depth", ["render=depth"]).name == "render-depth"


def test_help_builds_without_importing_the_stage_modules():
    code = (
        "import sys; from artic.cli.main import app; import typer; "
        "from artic.cli.registry import stage_entries; typer.main.get_command(app); "
        "mods = {e.module for e in stage_entries().values()}; "
        "print(sorted(m for m in sys.modules if m in mods "
        "or m.split('.')[0] in ('numpy', 'torch', 'hydra', 'pydantic', 'open3d')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_declaration_must_be_literal():
    source = 'HELP = "x"\nSTAGE = Stage(name="a", help=HELP, conf="a")\n'
    assert read_declaration("m", source).help == "x"  # a name bound to a literal
    with pytest.raises(RegistryError, match="not a literal"):
        read_declaration("m", 'STAGE = Stage(name="a", help=make_help())\n')
    assert read_declaration("m", "STAGES = []\n") is None


def test_render_scan_command_and_the_render_depth_alias(tiny_objects: Path, tmp_path: Path):
    direct, alias = tmp_path / "direct", tmp_path / "alias"
    code, _, err = run_cli("render-scan", *SMALL, f"dataset={tiny_objects}", f"out={direct}")
    assert code == 0, err
    code, _, err = run_cli(
        "render-depth", "render=scan", *SMALL, f"dataset={tiny_objects}", f"out={alias}"
    )
    assert code == 0, err
    assert "alias of artic render-scan" in err
    a, b = read_manifest(direct), read_manifest(alias)
    assert a.stage == b.stage == "render-scan"
    assert (a.config_hash, a.content_hash) == (b.config_hash, b.content_hash)
    # --cfg shows the preset; a conflicting render= is bad input
    code, out, _ = run_cli("render-scan", "--cfg", f"dataset={tiny_objects}")
    assert code == 0 and "clean_points" in out
    code, _, err = run_cli("render-scan", "render=depth", f"dataset={tiny_objects}")
    assert code == 2 and "render-scan always runs with render=scan" in err


def test_a_pipeline_runs_render_scan_by_name_or_by_alias(tmp_path: Path, tiny_objects: Path):
    for cmd, extra in (("render-scan", ""), ("render-depth", "render=scan, ")):
        path = tmp_path / f"{cmd}.yaml"
        path.write_text(
            f"stages: {{s: {{cmd: {cmd}, overrides: [{extra}debug=tiny, "
            f"dataset={tiny_objects}, out={tmp_path / 'scans'}]}}}}\n"
        )
        code, _, err = run_cli("pipeline", str(path), "--dry-run")
        assert code == 0, err
