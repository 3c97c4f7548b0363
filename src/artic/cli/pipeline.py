"""`artic pipeline NAME`: run the stages of `stages/NAME.yaml` in order.

A pipeline file maps stage names to `{cmd, overrides, deps, outs}`; `cmd` is a
registered stage's name (`cli/registry.py`), or an alias of one (`render-depth` with
`render=scan`). Each stage runs in this process through the same runner as its
subcommand, so an up-to-date stage is skipped by its own manifest check. `deps` must be
produced by an earlier stage or exist already; `outs` must name the folder the stage
writes.

A pipeline may declare `vars` with defaults (`vars: {task: drawer}`); `${task}` in any
override, dep or out is replaced by the value, which `artic pipeline NAME task=tball`
sets. Other `${...}` are left to Hydra's interpolation.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from rich.console import Console
from rich.table import Table

from artic.cli.registry import load_stage, resolve, say_alias, stage_entries
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
    vars: dict[str, str] = Field(default_factory=dict, description="variables and defaults")
    stages: dict[str, PipelineStage]

    def substituted(self, values: dict[str, str]) -> Pipeline:
        """The pipeline with `${name}` replaced by `values` (else the declared default)."""
        unknown = sorted(set(values) - set(self.vars))
        if unknown:
            known = ", ".join(sorted(self.vars)) or "none"
            raise InputError(
                f"pipeline variable '{unknown[0]}' is not declared (declared: {known})"
            )
        final = {**self.vars, **values}

        def sub(text: str) -> str:
            for name, value in final.items():
                text = text.replace("${" + name + "}", value)
            return text

        stages = {
            name: PipelineStage(
                cmd=st.cmd,
                overrides=[sub(o) for o in st.overrides],
                deps=[sub(d) for d in st.deps],
                outs=[sub(o) for o in st.outs],
            )
            for name, st in self.stages.items()
        }
        return Pipeline(description=self.description, vars=final, stages=stages)


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


def parse_vars(assignments: list[str]) -> dict[str, str]:
    """`["task=drawer"]` -> `{"task": "drawer"}`; a malformed item is an InputError."""
    values: dict[str, str] = {}
    for item in assignments:
        name, sep, value = item.partition("=")
        if not sep or not name.isidentifier() or not value:
            raise InputError(f"pipeline variable '{item}': expected NAME=VALUE")
        values[name] = value
    return values


def load_pipeline(path: Path, values: dict[str, str] | None = None) -> Pipeline:
    try:
        data = yaml.safe_load(path.read_text())
        pipeline = Pipeline.model_validate(data).substituted(values or {})
    except yaml.YAMLError as err:
        raise InputError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    except ValidationError as err:
        first = err.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise InputError(f"{path}: field {loc}: {first['msg']}") from None
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
            if _norm(dep) not in produced and not Path(dep).exists():
                raise InputError(
                    f"{path}: stage {name}: dep {dep} is neither made by an earlier stage "
                    "nor present"
                )
        produced.update(_norm(o) for o in stage.outs)


def _norm(p: str) -> str:
    return Path(p).as_posix().rstrip("/")


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
        if spec.outs and _norm(out) not in {_norm(o) for o in spec.outs}:
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
