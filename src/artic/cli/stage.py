"""What a stage declares: `Stage` and its `Plan`. Read by the registry
(`cli/registry.py`) and run by the runner (`cli/stage_runner.py`, which re-exports both);
a module of its own so that neither of those imports the other's importer."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Generic, TypeVar

from artic.artifacts.workers import ChunkFn
from artic.config.schemas import StageConfig

C = TypeVar("C", bound=StageConfig)


@dataclass(frozen=True)
class Plan:
    """How a stage's work splits: `items[c]` samples in chunk c, counted in `unit`."""

    items: list[int]
    unit: str

    @property
    def n_chunks(self) -> int:
        return len(self.items)


@dataclass(frozen=True)
class Stage(Generic[C]):
    """What a subcommand tells the runner. `inputs` maps input names to the stage each
    must come from; `input_paths` reads them off the config; `chunk` must be a
    module-level function (it runs in worker processes).

    A module of `artic.cli` defining `STAGE = Stage(...)` registers the stage
    (`cli/registry.py`), and its command is generated from these fields: `help` (the
    command's help, first paragraph listed by `artic --help`), `command` (the words
    after `artic`, default the name; "evaluate mdn" is a subcommand of `evaluate`),
    `task_option` (`--task NAME`, shorthand for `task=NAME`), `preset` (overrides the
    stage always composes with, e.g. render-scan's `render=scan`), `options` (config
    fields also given as options: {"skills": "list"} reads `--skills a,b` as
    `skills=[a,b]`, {"perceive": "flag"} reads `--perceive` as `perceive=true`) and
    `alias` (another
    command line that runs this stage, with a log line saying so: "render-depth
    render=scan"). The registry reads these from the source without importing the
    module, so they must be literals. `one_chunk`: the plan always has one chunk, so the
    stage cannot be split into shards (the cluster launcher refuses to)."""

    name: str
    conf: str
    schema: type[C]
    plan: Callable[[C, dict[str, Path]], Plan]
    chunk: ChunkFn
    finalize: Callable[[C, dict[str, Path], Path], dict[str, float | int | str]]
    inputs: dict[str, str] = field(default_factory=dict)
    input_paths: Callable[[C], dict[str, Path]] = lambda cfg: {}
    help: str = ""
    command: str = ""
    task_option: bool = False
    preset: tuple[str, ...] = ()
    options: dict[str, str] = field(default_factory=dict)
    alias: str = ""
    #: the stage's work is always one chunk (a training run, one evaluation): no shards
    one_chunk: bool = False
