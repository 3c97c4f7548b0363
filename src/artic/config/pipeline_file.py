"""Pipeline files (`stages/NAME.yaml`, run by `artic pipeline NAME`) parsed and validated.

A pipeline file maps stage names to `{cmd, overrides, deps, outs}`. It may declare `vars`
with defaults (`vars: {task: drawer}`); `${task}` in any override, dep or out is replaced
by the value (`artic pipeline NAME task=tball` sets it). Other `${...}` are left to
Hydra's interpolation. Pure: the caller reads the file and checks its stages against the
stage registry and the file system.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

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
        loc = ".".join(str(p) for p in first["loc"])
        raise InputError(f"{source}: field {loc}: {first['msg']}") from None


def norm(path: str) -> str:
    """A dep or out as compared between stages: posix, no trailing slash."""
    return Path(path).as_posix().rstrip("/")
