"""The stage registry: which stages exist, which module defines each, and how each
appears on the command line.

A stage registers itself: a module of `artic.cli` that defines `STAGE = Stage(...)`
(`cli/stage.Stage`) is a stage module, and its declaration says everything the
command line needs (`name`, `help`, `command`, `task_option`, `preset`, `options`,
`alias`).
Nothing else lists the stages: `cli/main.py` generates one command per entry, `artic
pipeline` resolves `cmd:` here, and the runner finds here the stage that wrote an input.

`artic --help` must stay fast, and the stage modules import NumPy, PyTorch or PyBullet,
so the registry reads the declarations from the modules' source (`ast`; the fields it
reads must be literals, or names bound to literals at module level) and imports a stage
module only when its stage runs (`load_stage`). tests/cli/test_registry.py checks that
what it reads equals what the imported modules define.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import importlib
import logging
import pkgutil
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from artic.errors import InputError

if TYPE_CHECKING:
    from artic.cli.stage import Stage

log = logging.getLogger("artic")

PACKAGE = "artic.cli"
_DIR = Path(__file__).parent
#: `STAGE = Stage(` or `STAGE: Stage[X] = Stage(` at the start of a line
_DECLARATION = re.compile(r"^STAGE\b[^=\n]*=\s*Stage\(", re.MULTILINE)
#: the Stage fields read from the source, with their defaults
_FIELDS: dict[str, Any] = {
    "name": None,
    "help": "",
    "command": "",
    "task_option": False,
    "preset": (),
    "options": {},
    "alias": "",
    "inputs": {},
}


class RegistryError(Exception):
    """A stage declaration the registry cannot read (a programming error)."""


@dataclass(frozen=True)
class StageEntry:
    """One registered stage, as declared in its module (read without importing it)."""

    name: str
    module: str
    help: str = ""
    #: the words after `artic`: ("train-mdn",) or ("evaluate", "mdn")
    command: tuple[str, ...] = ()
    task_option: bool = False
    preset: tuple[str, ...] = ()
    #: config fields also given as options: {"skills": "list", "perceive": "flag"}
    options: dict[str, str] = field(default_factory=dict, hash=False)
    #: another command line that runs this stage: ("render-depth", "render=scan")
    alias: tuple[str, ...] = ()
    inputs: dict[str, str] = field(default_factory=dict, hash=False)


def _literal(node: ast.expr, names: dict[str, Any], where: str) -> Any:
    if isinstance(node, ast.Name):
        if node.id not in names:
            raise RegistryError(f"{where}: {node.id} is not a literal bound at module level")
        return names[node.id]
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise RegistryError(f"{where}: not a literal: {ast.unparse(node)}") from None


def _module_constant(source: str, name: str) -> dict[str, Any]:
    """`{name: value}` when `source` binds `name = literal` on one line at module
    level (read without parsing the whole module), else {}."""
    line = re.search(rf"^{name}\b[^=\n]*=(.*)$", source, re.MULTILINE)
    if line is not None:
        try:
            return {name: ast.literal_eval(line.group(1).strip())}
        except (ValueError, SyntaxError):
            pass
    return {}


def _module_constants(source: str) -> dict[str, Any]:
    """Module-level `NAME = literal` bindings of `source`."""
    constants: dict[str, Any] = {}
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target, value = node.targets[0], node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            target, value = node.target, node.value
        else:
            continue
        if isinstance(target, ast.Name):
            with contextlib.suppress(ValueError):
                constants[target.id] = ast.literal_eval(value)
    return constants


def read_declaration(module: str, source: str) -> StageEntry | None:
    """The entry declared by `STAGE = Stage(...)` in `source`, or None if there is none."""
    found = _DECLARATION.search(source)
    if found is None:
        return None
    # the declaration to the end of the file: complete statements, parsed quickly
    tail = ast.parse(source[found.start() :])
    stmt = tail.body[0]
    call = stmt.value if isinstance(stmt, ast.Assign | ast.AnnAssign) else None
    if not isinstance(call, ast.Call) or call.args:
        raise RegistryError(f"{module}: STAGE = Stage(...) must take keyword arguments only")
    names: dict[str, Any] = {}
    for kw in call.keywords:
        if kw.arg in _FIELDS and isinstance(kw.value, ast.Name) and kw.value.id not in names:
            names.update(_module_constant(source, kw.value.id))
            if kw.value.id not in names:
                names = _module_constants(source)  # a binding over several lines
    values = dict(_FIELDS)
    for kw in call.keywords:
        if kw.arg in _FIELDS:
            values[kw.arg] = _literal(kw.value, names, f"{module}: Stage({kw.arg}=...)")
    name = values["name"]
    if not isinstance(name, str) or not name:
        raise RegistryError(f"{module}: Stage(name=...) must be a non-empty string")
    return StageEntry(
        name=name,
        module=module,
        help=values["help"],
        command=tuple((values["command"] or name).split()),
        task_option=bool(values["task_option"]),
        preset=tuple(values["preset"]),
        options=dict(values["options"]),
        alias=tuple(values["alias"].split()),
        inputs=dict(values["inputs"]),
    )


def _depth(name: str, entries: dict[str, StageEntry], seen: tuple[str, ...] = ()) -> int:
    """Longest chain of inputs leading to the stage (0: it reads no stage's output)."""
    if name in seen:
        raise RegistryError(f"stage inputs form a cycle: {' -> '.join([*seen, name])}")
    ups = [s for s in entries[name].inputs.values() if s in entries]
    return 1 + max(_depth(s, entries, (*seen, name)) for s in ups) if ups else 0


@functools.cache
def stage_entries() -> dict[str, StageEntry]:
    """Every registered stage by name, in pipeline order (a stage after the stages
    whose outputs it reads; then by name)."""
    found: dict[str, StageEntry] = {}
    commands: dict[tuple[str, ...], str] = {}
    for info in pkgutil.iter_modules([str(_DIR)]):
        path = _DIR / f"{info.name}.py"
        if info.ispkg or not path.is_file():
            continue
        source = path.read_text(encoding="utf-8")
        if "Stage(" not in source:
            continue
        entry = read_declaration(f"{PACKAGE}.{info.name}", source)
        if entry is None:
            continue
        for clash in (found.get(entry.name), commands.get(entry.command)):
            if clash is not None:
                other = clash if isinstance(clash, str) else clash.module
                raise RegistryError(f"{entry.module}: stage {entry.name} also in {other}")
        found[entry.name] = entry
        commands[entry.command] = entry.module
    order = sorted(found, key=lambda n: (_depth(n, found), n))
    return {n: found[n] for n in order}


def load_stage(name: str) -> Stage[Any]:
    """The `Stage` registered as `name` (imports its module)."""
    entries = stage_entries()
    if name not in entries:
        raise InputError(f"unknown stage '{name}' (known: {', '.join(sorted(entries))})")
    stage: Stage[Any] = importlib.import_module(entries[name].module).STAGE
    if stage.name != name:
        raise RegistryError(f"{entries[name].module}: STAGE.name is {stage.name}, not {name}")
    return stage


def resolve(command: str, overrides: list[str] | None) -> StageEntry:
    """The stage that `artic COMMAND OVERRIDES` (or a pipeline's `cmd: COMMAND`) runs:
    the stage named COMMAND, or the stage whose `alias` is COMMAND with one of
    OVERRIDES (`render-depth render=scan` runs render-scan; see `say_alias`)."""
    entries = stage_entries()
    given = set(overrides or [])
    for entry in entries.values():
        if entry.alias and entry.alias[0] == command and set(entry.alias[1:]) <= given:
            return entry
    if command not in entries:
        raise InputError(f"unknown stage '{command}' (known: {', '.join(sorted(entries))})")
    return entries[command]


def say_alias(command: str, entry: StageEntry) -> None:
    """Log that COMMAND was an alias of the stage `entry`'s command. Said once the stage
    has run: bad input stays one line on stderr."""
    if entry.name != command:
        log.info(
            "artic %s is an alias of artic %s (the %s stage)",
            " ".join(entry.alias),
            " ".join(entry.command),
            entry.name,
        )
