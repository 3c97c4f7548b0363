"""`artic pipeline NAME`: run the stages of `stages/NAME.yaml` in order.

A pipeline file maps stage names to `{cmd, overrides, deps, outs}`. Each stage runs
in this process through the same runner as its subcommand, so an up-to-date stage is
skipped by its own manifest check. `deps` must be produced by an earlier stage or
exist already; `outs` must name the folder the stage writes.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from rich.console import Console
from rich.table import Table

from artic.config.compose import conf_dir
from artic.errors import InputError


class PipelineStage(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    cmd: str = Field(description="subcommand, e.g. generate-dataset")
    overrides: list[str] = Field(default_factory=list, description="Hydra overrides")
    deps: list[str] = Field(default_factory=list, description="input folders")
    outs: list[str] = Field(default_factory=list, description="output folders")


class Pipeline(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    description: str = ""
    stages: dict[str, PipelineStage]


def pipeline_path(name: str) -> Path:
    """`stages/NAME.yaml` beside conf/, or NAME itself when it is a file."""
    direct = Path(name)
    if direct.suffix in (".yaml", ".yml") and direct.is_file():
        return direct
    path = conf_dir().parent / "stages" / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in path.parent.glob("*.yaml"))
        raise InputError(f"pipeline '{name}': no {path} (known: {', '.join(known)})")
    return path


def load_pipeline(path: Path) -> Pipeline:
    try:
        data = yaml.safe_load(path.read_text())
        pipeline = Pipeline.model_validate(data)
    except yaml.YAMLError as err:
        raise InputError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    except ValidationError as err:
        first = err.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise InputError(f"{path}: field {loc}: {first['msg']}") from None
    _check(path, pipeline)
    return pipeline


def _check(path: Path, pipeline: Pipeline) -> None:
    from artic.cli.main import STAGE_MODULES

    produced: set[str] = set()
    for name, stage in pipeline.stages.items():
        if stage.cmd not in STAGE_MODULES:
            raise InputError(
                f"{path}: stage {name}: unknown cmd '{stage.cmd}' "
                f"(known: {', '.join(sorted(STAGE_MODULES))})"
            )
        for dep in stage.deps:
            if _norm(dep) not in produced and not Path(dep).exists():
                raise InputError(
                    f"{path}: stage {name}: dep {dep} is neither made by an earlier stage "
                    "nor present"
                )
        produced.update(_norm(o) for o in stage.outs)


def _norm(p: str) -> str:
    return Path(p).as_posix().rstrip("/")


def run_pipeline(name: str, force: bool = False, dry_run: bool = False) -> None:
    from artic.cli.main import load_stage
    from artic.cli.stage_runner import resolved_config, run_stage

    path = pipeline_path(name)
    pipeline = load_pipeline(path)
    console = Console()
    verbose = logging.getLogger().isEnabledFor(logging.INFO)  # not under --quiet
    table = Table(title=f"pipeline {name} ({path})", title_justify="left")
    for col in ("stage", "cmd", "status", "seconds", "output"):
        table.add_column(col)
    for stage_name, spec in pipeline.stages.items():
        stage = load_stage(spec.cmd)
        out = str(resolved_config(stage, spec.overrides)["out"])
        if spec.outs and _norm(out) not in {_norm(o) for o in spec.outs}:
            raise InputError(f"{path}: stage {stage_name}: writes {out}, not listed in its outs")
        if dry_run:
            table.add_row(stage_name, spec.cmd, "planned", "", out)
            continue
        if verbose:
            console.print(f"[bold]{stage_name}[/]: artic {spec.cmd} {' '.join(spec.overrides)}")
        t0 = time.perf_counter()
        result = run_stage(stage, spec.overrides, force=force)
        if result.status == "partial":
            raise InputError(f"{path}: stage {stage_name} did not finish: {result.message}")
        table.add_row(stage_name, spec.cmd, result.status, f"{time.perf_counter() - t0:.1f}", out)
    if verbose or dry_run:
        console.print(table)
