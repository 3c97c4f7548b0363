"""Pipeline files (`stages/NAME.yaml`, run by `artic pipeline NAME`) parsed and validated.

A pipeline file maps stage names to `{cmd, overrides, deps, outs, resources}`
(`resources`: what a cluster job of the stage needs, read by `artic pipeline NAME
launcher=...`: `artic.config.launcher.Resources`). It may declare `vars`
with defaults (`vars: {task: drawer}`); `${task}` in any override, dep or out is replaced
by the value (`artic pipeline NAME task=tball` sets it). Other `${...}` are left to
Hydra's interpolation. `load_pipeline` reads a file (`pipeline_path`: found by name in
`stages/`) and checks its stages against the stage names the caller gives (the stage
registry's) and the file system; the rest is pure.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from artic.config.compose import stages_dir
from artic.config.launcher import UNION_TAG, Resources
from artic.errors import InputError


class PipelineStage(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    cmd: str = Field(description="subcommand, e.g. generate-dataset")
    overrides: list[str] = Field(default_factory=list, description="Hydra overrides")
    deps: list[str] = Field(default_factory=list, description="input folders")
    outs: list[str] = Field(default_factory=list, description="output folders")
    resources: Resources | None = Field(
        None, description="launcher hints: shards, time, CPUs, memory, GPUs of its jobs"
    )


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
                resources=st.resources,
            )
            for name, st in self.stages.items()
        }
        return Pipeline(description=self.description, vars=final, stages=stages)


def parse_vars(assignments: list[str]) -> dict[str, str]:
    """`["task=drawer"]` -> `{"task": "drawer"}`; a malformed item is an InputError."""
    values: dict[str, str] = {}
    for item in assignments:
        name, sep, value = item.partition("=")
        if not sep or not name.isidentifier() or not value:
            raise InputError(f"pipeline variable '{item}': expected NAME=VALUE")
        values[name] = value
    return values


def parse_pipeline(text: str, source: str, values: dict[str, str] | None = None) -> Pipeline:
    """The pipeline of YAML `text` (read from `source`, named in errors), substituted."""
    try:
        data = yaml.safe_load(text)
        return Pipeline.model_validate(data).substituted(values or {})
    except yaml.YAMLError as err:
        raise InputError(f"{source}: not valid YAML ({str(err).splitlines()[0]})") from None
    except ValidationError as err:
        first = err.errors()[0]
        loc = ".".join(str(p) for p in first["loc"] if not UNION_TAG.match(str(p)))
        raise InputError(f"{source}: field {loc}: {first['msg']}") from None


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


def load_pipeline(
    path: Path, known: Collection[str], values: dict[str, str] | None = None
) -> Pipeline:
    """The pipeline of file `path`, substituted (`values`), its stages checked: every
    `cmd` one of `known` (the stage registry's names), every dep made by an earlier stage
    or present."""
    pipeline = parse_pipeline(path.read_text(), str(path), values)
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
    return pipeline


def norm(path: str) -> str:
    """A dep or out as compared between stages: posix, no trailing slash."""
    return Path(path).as_posix().rstrip("/")


def common_folder(outs: list[str]) -> str:
    """The folder the outputs `outs` share ("" for fewer than two, none, or a mix of
    absolute and relative paths)."""
    if len(outs) < 2:
        return ""
    try:
        common = os.path.commonpath([Path(o).as_posix() for o in outs])
    except ValueError:  # absolute and relative mixed
        return ""
    return "" if common in ("", ".", "/") else common


def relative_out(out: str, common: str) -> str:
    """`out` relative to the outputs' `common_folder`."""
    if not common:
        return out
    return Path(out).as_posix().removeprefix(common + "/") or out


def overrides_taken(
    source: str,
    pipeline: Pipeline,
    extra: list[str],
    compose: Callable[[PipelineStage, list[str]], dict[str, Any]],
) -> dict[str, list[str]]:
    """Which of the overrides `extra` (`seeds=2 updates=10`) each stage takes: those its
    config composes with (`compose(stage, overrides)` raises InputError otherwise: a key
    it does not have, a config group it does not have). An override no stage takes is
    bad input naming the closest keys of the stages' configs."""
    given: dict[str, list[str]] = {name: [] for name in pipeline.stages}
    for override in extra:
        if "=" not in override:
            raise InputError(f"override '{override}': expected KEY=VALUE")
        takers = []
        for name, spec in pipeline.stages.items():
            try:
                compose(spec, [*spec.overrides, override])
            except InputError:
                continue
            takers.append(name)
        if not takers:
            key = override.partition("=")[0].lstrip("+~")
            keys = {
                k
                for spec in pipeline.stages.values()
                for k in _dotted(compose(spec, spec.overrides))
            }
            close = difflib.get_close_matches(key, sorted(keys), n=3)
            hint = f"; did you mean {' or '.join(close)}?" if close else ""
            raise InputError(f"{source}: override {override}: no stage takes key '{key}'{hint}")
        for name in takers:
            given[name].append(override)
    return given


def _dotted(config: dict[str, Any], prefix: str = "") -> list[str]:
    """Every key of a nested config, dotted (`train.epochs`)."""
    keys = []
    for k, v in config.items():
        keys.append(prefix + str(k))
        if isinstance(v, dict):
            keys += _dotted(v, f"{prefix}{k}.")
    return keys
