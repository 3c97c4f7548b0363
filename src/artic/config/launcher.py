"""How `artic pipeline NAME launcher=...` runs a pipeline's stages: the launcher configs
`conf/launcher/{inline,local,slurm}.yaml`, validated, and the resources of one stage.

A launcher config names the executor (`inline`: every stage in this process, as without
a launcher; `local`: submitit's local executor, each job a separate process; `slurm`:
submitit's SLURM executor) and the default resources of a job, spelt as Hydra's
submitit launcher spells them (`timeout_min`, `cpus_per_task`, `gpus_per_node`,
`mem_gb`, `partition`, `array_parallelism`, ...). A stage's resources come from, in
order (later wins): these defaults, the stage's `resources:` hints in its pipeline file,
the launcher config's `stages:` entries whose pattern matches the stage's name
(`fnmatch`, e.g. `train-*`). Overrides on the command line are dotted keys
(`launcher.partition=gpu`, `launcher.stages.train-*.timeout_min=120`). Also: the
submitit parameters of a job with given resources (`executor_parameters`).
"""

from __future__ import annotations

import re
import shlex
import sys
from collections.abc import Sequence
from fnmatch import fnmatchcase
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from artic.errors import InputError

LAUNCHERS = ("inline", "local", "slurm")


class Resources(BaseModel):
    """What one stage's jobs ask for; a field left None takes the value of the level
    below (the launcher's defaults)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    shards: Annotated[int, Field(ge=1)] | Literal["chunks"] | None = Field(
        None,
        description="array jobs the stage is split into (shard.index/shard.count); "
        "'chunks' = one per chunk of work (e.g. one per seed), 1 = a single job",
    )
    timeout_min: int | None = Field(None, gt=0, description="wall-time limit of a job, minutes")
    cpus_per_task: int | None = Field(None, gt=0, description="CPUs of a job")
    gpus_per_node: int | None = Field(None, ge=0, description="GPUs of a job")
    mem_gb: float | None = Field(None, gt=0, description="memory of a job, GB")
    partition: str | None = Field(None, description="SLURM partition")
    array_parallelism: int | None = Field(
        None, gt=0, description="array jobs of a stage running at once"
    )

    def over(self, base: Resources) -> Resources:
        """These resources, with `base`'s values where this has none."""
        mine = self.model_dump(exclude_none=True)
        return base.model_copy(update=mine)


class LauncherConfig(BaseModel):
    """One launcher: the executor and the default resources of its jobs."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: Literal["inline", "local", "slurm"] = Field(description="the executor")
    defaults: Resources = Field(
        default_factory=lambda: Resources(
            shards=1, timeout_min=60, cpus_per_task=1, gpus_per_node=0, mem_gb=4.0
        ),
        description="resources of every job unless a stage says otherwise",
    )
    stages: dict[str, Resources] = Field(
        default_factory=dict,
        description="per-stage overrides, keyed by a pattern of stage names (fnmatch)",
    )
    qos: str | None = Field(None, description="SLURM quality of service")
    account: str | None = Field(None, description="SLURM account charged")
    constraint: str | None = Field(None, description="SLURM node features, e.g. a GPU model")
    setup: list[str] = Field(
        default_factory=list,
        description="shell lines run in each sbatch script before the job (module load ...)",
    )
    additional_parameters: dict[str, str] = Field(
        default_factory=dict, description="more sbatch options, verbatim (mail-user: ...)"
    )
    slurm: dict[str, Any] = Field(
        default_factory=dict,
        description="more parameters of submitit's SlurmExecutor by its names "
        "(exclusive, gres, nodelist, ...); submitit rejects unknown ones",
    )
    poll_s: float = Field(1.0, gt=0, description="local: seconds between looks at running jobs")

    def resources(self, stage: str, hints: Resources | None = None) -> Resources:
        """The resources of pipeline stage `stage`: defaults < pipeline hints < this
        config's `stages:` entries matching the name (in file order)."""
        result = self.defaults if hints is None else hints.over(self.defaults)
        for pattern, extra in self.stages.items():
            if fnmatchcase(stage, pattern):
                result = extra.over(result)
        return result


def parse_launcher(
    text: str, source: str, overrides: dict[str, str] | None = None
) -> LauncherConfig:
    """The launcher config of YAML `text` (read from `source`, named in errors) with the
    dotted `overrides` (`{"partition": "gpu", "stages.train-*.gpus_per_node": "1"}`,
    values parsed as YAML scalars) applied."""
    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as err:
        raise InputError(f"{source}: not valid YAML ({str(err).splitlines()[0]})") from None
    if not isinstance(data, dict):
        raise InputError(f"{source}: expected a mapping of launcher settings")
    for dotted, value in (overrides or {}).items():
        _set(data, dotted, value, source)
    try:
        return LauncherConfig.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        loc = ".".join(str(p) for p in first["loc"] if not UNION_TAG.match(str(p)))
        raise InputError(f"{source}: launcher.{loc}: {first['msg']}") from None


#: pydantic's names of union members in an error's location (shards: int | "chunks")
UNION_TAG = re.compile(r"^(constrained-\w+|int|str|float|literal\[.*\])$")

#: keys of the launcher config a stage's resources live under: `launcher.timeout_min=`
#: is read as `launcher.defaults.timeout_min=`
_RESOURCE_KEYS = frozenset(Resources.model_fields)


def _set(data: dict[str, Any], dotted: str, value: str, source: str) -> None:
    parts = dotted.split(".")
    if parts[0] in _RESOURCE_KEYS:
        parts = ["defaults", *parts]
    if parts[0] == "stages" and len(parts) != 3:
        raise InputError(f"launcher.{dotted}: expected launcher.stages.PATTERN.FIELD=VALUE")
    node = data
    for key in parts[:-1]:
        child = node.setdefault(key, {})
        if not isinstance(child, dict):
            raise InputError(f"{source}: launcher.{dotted}: {key} is not a mapping")
        node = child
    try:
        node[parts[-1]] = yaml.safe_load(value) if value != "" else None
    except yaml.YAMLError:
        node[parts[-1]] = value


def split_launcher_args(args: Sequence[str]) -> tuple[str, dict[str, str], list[str]]:
    """`launcher=NAME` and `launcher.KEY=VALUE` out of a pipeline's arguments: the
    launcher's name (default inline), its overrides, and the other arguments."""
    name, overrides, rest = "inline", {}, []
    for arg in args:
        key, sep, value = arg.partition("=")
        if sep and key == "launcher":
            name = value
        elif sep and key.startswith("launcher."):
            overrides[key.removeprefix("launcher.")] = value
        else:
            rest.append(arg)
    return name, overrides, rest


def load_launcher(name: str, overrides: dict[str, str] | None = None) -> LauncherConfig:
    """`conf/launcher/NAME.yaml` with `overrides`; an unknown launcher is bad input."""
    from artic.config.compose import conf_dir

    path = conf_dir() / "launcher" / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in path.parent.glob("*.yaml")) or list(LAUNCHERS)
        raise InputError(f"launcher={name}: unknown launcher (known: {', '.join(known)})")
    return parse_launcher(path.read_text(), str(path), overrides)


#: an sbatch script's line pinning the numerical kernels on the node the job runs on
#: (`artic.reproducibility`, as the `artic` command does), before its Python loads NumPy
PIN_LINE = (
    'eval "$(' + shlex.quote(sys.executable) + " -c 'import os, shlex; "
    "from artic.reproducibility import pin_numerics; e = dict(os.environ); "
    "pin_numerics(e); "
    'print(" ".join(f"export {k}={shlex.quote(v)}" for k, v in e.items() '
    "if k not in os.environ))')\""
)


def executor_parameters(launcher: LauncherConfig, r: Resources, name: str) -> dict[str, Any]:
    """The submitit AutoExecutor parameters of a job with resources `r`: the generic
    names as Hydra's submitit launcher passes them, the SLURM-only ones prefixed
    `slurm_` (validated by submitit, for the local executor too)."""
    params: dict[str, Any] = {
        "name": name,
        "timeout_min": r.timeout_min,
        "cpus_per_task": r.cpus_per_task,
        "gpus_per_node": r.gpus_per_node,
        "mem_gb": r.mem_gb,
    }
    if launcher.name == "slurm":
        params.update(
            slurm_partition=r.partition,
            slurm_array_parallelism=r.array_parallelism,
            slurm_qos=launcher.qos,
            slurm_account=launcher.account,
            slurm_constraint=launcher.constraint,
            slurm_setup=[*launcher.setup, PIN_LINE],
            slurm_additional_parameters=dict(launcher.additional_parameters) or None,
        )
    params.update({f"slurm_{k}": v for k, v in launcher.slurm.items()})
    return {k: v for k, v in params.items() if v is not None}
