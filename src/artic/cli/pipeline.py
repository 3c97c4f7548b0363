"""`artic pipeline NAME`: run the stages of `stages/NAME.yaml` in order.

A pipeline file (`artic.config.pipeline_file`: its schema, `vars` and `${...}`
substitution) maps stage names to `{cmd, overrides, deps, outs}`; `cmd` is a
registered stage's name (`cli/registry.py`), or an alias of one (`render-depth` with
`render=scan`). Each stage runs in this process through the same runner as its
subcommand, so an up-to-date stage is skipped by its own manifest check. `deps` must be
produced by an earlier stage or exist already; `outs` must name the folder the stage
writes.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from artic.cli.registry import load_stage, resolve, say_alias, stage_entries
from artic.config.compose import stages_dir
from artic.config.pipeline_file import Pipeline, norm, parse_pipeline
from artic.config.pipeline_file import parse_vars as parse_vars
from artic.errors import InputError


def pipeline_path(name: str) -> Path:
    """`stages/NAME.yaml` (the shipped pipelines, or those beside `$ARTIC_CONF`), or NAME
    itself when it is a file."""
    direct = Path(name)
    if direct.suffix in (".yaml", ".yml") and direct.is_file():
        return direct
    path = stages_dir() / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in path.parent.glob("*.yaml"))
        raise InputError(f"pipeline '{name}': no {path} (known: {', '.join(known)})")
    return path


def load_pipeline(path: Path, values: dict[str, str] | None = None) -> Pipeline:
    pipeline = parse_pipeline(path.read_text(), str(path), values)
    _check(path, pipeline)
    return pipeline


def _check(path: Path, pipeline: Pipeline) -> None:
    known = stage_entries()
    produced: set[str] = set()
    for name, stage in pipeline.stages.items():
        if stage.cmd not in known:
            raise InputError(
                f"{path}: stage {name}: unknown cmd '{stage.cmd}' "
                f"(known: {', '.join(sorted(known))})"
            )
        for dep in stage.deps:
            if norm(dep) not in produced and not Path(dep).exists():
                raise InputError(
                    f"{path}: stage {name}: dep {dep} is neither made by an earlier stage "
                    "nor present"
                )
        produced.update(norm(o) for o in stage.outs)


def run_pipeline(
    name: str,
    force: bool = False,
    dry_run: bool = False,
    values: dict[str, str] | None = None,
) -> None:
    from artic.cli.stage_runner import resolved_config, run_stage
    from artic.config.compose import validate

    path = pipeline_path(name)
    pipeline = load_pipeline(path, values)
    console = Console()
    verbose = logging.getLogger().isEnabledFor(logging.INFO)  # not under --quiet
    table = Table(title=f"pipeline {name} ({path})", title_justify="left")
    for col in ("stage", "cmd", "status", "seconds", "output"):
        table.add_column(col)
    # every stage's config is composed and validated before the first one runs (a later
    # stage's inputs may not exist yet: they are checked when that stage runs)
    planned = []
    for stage_name, spec in pipeline.stages.items():
        entry = resolve(spec.cmd, spec.overrides)
        stage = load_stage(entry.name)
        try:
            raw = resolved_config(stage, spec.overrides)
            validate(stage.schema, raw)
        except InputError as err:
            raise InputError(f"{path}: stage {stage_name}: {err}") from None
        out = str(raw["out"])
        if spec.outs and norm(out) not in {norm(o) for o in spec.outs}:
            raise InputError(f"{path}: stage {stage_name}: writes {out}, not listed in its outs")
        planned.append((stage_name, spec, entry, stage, out))
    for stage_name, spec, entry, stage, out in planned:
        if dry_run:
            table.add_row(stage_name, spec.cmd, "planned", "", out)
            continue
        if verbose:
            console.print(f"[bold]{stage_name}[/]: artic {spec.cmd} {' '.join(spec.overrides)}")
        t0 = time.perf_counter()
        result = run_stage(stage, spec.overrides, force=force)
        say_alias(spec.cmd, entry)
        if result.status == "partial":
            raise InputError(f"{path}: stage {stage_name} did not finish: {result.message}")
        table.add_row(stage_name, spec.cmd, result.status, f"{time.perf_counter() - t0:.1f}", out)
    if verbose or dry_run:
        console.print(table)
