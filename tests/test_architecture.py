"""The import structure of src/artic, as docs/architecture.md ("Layers") documents it.

Every module is parsed with `ast` (nothing is imported) and every import counts, at any
level: module top, inside functions, under `if TYPE_CHECKING:`. The rules:

- no library module (outside `artic.cli` and `artic.__main__`) imports `artic.cli`;
- no stage module (a module of `artic.cli` defining a module-level `STAGE`) imports
  another stage module, directly or through other modules of `artic.cli`;
- no import cycle between modules of `artic.cli`;
- every package sits on a floor of the Layers table of docs/architecture.md, and a
  package imports only packages on lower floors (never its own floor or higher);
- `src/artic/cli/*.py` holds fewer than 4,000 lines.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = SRC / "artic"
ARCHITECTURE = ROOT / "docs" / "architecture.md"
CLI = "artic.cli"
CLI_MAX_LINES = 4000  # Chapter 7 adds five stages of ~80 lines (docs/architecture.md)


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


@cache
def modules() -> dict[str, Path]:
    """Every module of src/artic: dotted name -> file."""
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


@cache
def _tree(name: str) -> ast.Module:
    path = modules()[name]
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _imported(name: str, node: ast.Import | ast.ImportFrom) -> Iterator[str]:
    """The artic modules one import statement of module `name` imports."""
    if isinstance(node, ast.Import):
        targets = [alias.name for alias in node.names]
    else:
        if node.level:
            is_package = modules()[name].name == "__init__.py"
            base = name.split(".") if is_package else name.split(".")[:-1]
            base = base[: len(base) - (node.level - 1)]
            module = ".".join([*base, node.module] if node.module else base)
        else:
            module = node.module or ""
        # `from artic.hierarchy import types` imports the module artic.hierarchy.types
        subs = [f"{module}.{alias.name}" for alias in node.names]
        targets = [module, *(s for s in subs if s in modules())]
    for target in targets:
        if target == "artic" or target.startswith("artic."):
            while target not in modules() and "." in target:
                target = target.rsplit(".", 1)[0]  # an attribute of a module, e.g. a class
            yield target


@cache
def imports() -> dict[str, frozenset[str]]:
    """Module -> the artic modules it imports (anywhere in its body)."""
    graph: dict[str, frozenset[str]] = {}
    for name in modules():
        found = {
            target
            for node in ast.walk(_tree(name))
            if isinstance(node, ast.Import | ast.ImportFrom)
            for target in _imported(name, node)
        }
        found.discard(name)
        graph[name] = frozenset(found)
    return graph


def package_of(module: str) -> str:
    """The floor-table key of a module: `artic` for the package root, `cli` for
    `artic.__main__` (the front door's other entry), else the name after `artic.`
    (`artic.objects.tree` -> `objects`, `artic.errors` -> `errors`)."""
    parts = module.split(".")
    if module == "artic.__main__":
        return "cli"
    return parts[1] if len(parts) > 1 else "artic"


def is_cli(module: str) -> bool:
    return module == CLI or module.startswith(CLI + ".")


def stage_modules() -> set[str]:
    """Modules of artic.cli that define a module-level `STAGE` (the stage registry's own
    criterion: a stage registers itself by defining it)."""

    def defines_stage(node: ast.stmt) -> bool:
        if isinstance(node, ast.Assign):
            return any(isinstance(t, ast.Name) and t.id == "STAGE" for t in node.targets)
        return (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and node.target.id == "STAGE"
        )

    return {
        name
        for name in modules()
        if is_cli(name) and any(defines_stage(node) for node in _tree(name).body)
    }


@cache
def floors() -> dict[str, int]:
    """Package -> floor, read from the table of the "## Layers" section of
    docs/architecture.md: rows `| <floor> | <packages in backticks> | ...`."""
    text = ARCHITECTURE.read_text(encoding="utf-8")
    section = re.search(r"^## Layers\n(.*?)(?=^## )", text, re.MULTILINE | re.DOTALL)
    assert section, f"{ARCHITECTURE}: no '## Layers' section"
    table: dict[str, int] = {}
    for floor, cell in re.findall(r"^\| *(\d+) *\| *([^|]*)\|", section.group(1), re.MULTILINE):
        for name in re.findall(r"`([^`]+)`", cell):
            key = name.strip().removesuffix("/").removesuffix(".py")
            assert key not in table, f"{key} is on two floors of the Layers table"
            table[key] = int(floor)
    return table


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


# --- the checker itself sees what it must see ---------------------------------------


def test_the_checker_reads_imports_at_every_level() -> None:
    graph = imports()
    assert "artic.reproducibility" in graph["artic.artifacts.manifest"]  # top level
    assert "artic.objects.tree" in graph["artic.render.depth"]  # inside a function
    assert "artic.objects.tree" in graph["artic.artifacts.scan_dataset"]  # TYPE_CHECKING
    assert "artic.cli.render_scan" in stage_modules()
    assert "artic.cli.stage_runner" not in stage_modules()


def test_every_package_is_on_a_floor() -> None:
    table = floors()
    assert table.get("cli") == max(table.values())
    missing = sorted({package_of(m) for m in modules()} - set(table))
    assert not missing, f"put these on a floor of docs/architecture.md (## Layers): {missing}"


# --- the rules ---------------------------------------------------------------------


def test_no_library_module_imports_the_cli() -> None:
    bad = [
        f"{m} -> {t}"
        for m, targets in sorted(imports().items())
        if not is_cli(m) and m != "artic.__main__"
        for t in sorted(targets)
        if is_cli(t)
    ]
    assert not bad, "library modules import artic.cli:\n" + "\n".join(bad)


def test_no_upward_arrow_between_floors() -> None:
    table = floors()
    bad = [
        f"{m} (floor {table[package_of(m)]}) -> {t} (floor {table[package_of(t)]})"
        for m, targets in sorted(imports().items())
        for t in sorted(targets)
        if package_of(m) != package_of(t)
        and package_of(m) in table
        and package_of(t) in table
        and table[package_of(t)] >= table[package_of(m)]
    ]
    assert not bad, "imports of a package on the same or a higher floor:\n" + "\n".join(bad)


def test_no_stage_module_imports_another() -> None:
    graph = imports()
    stages = stage_modules()
    bad = []
    for stage in sorted(stages):
        # breadth-first through modules of artic.cli, so a helper cannot launder the arrow
        path = {stage: [stage]}
        queue = [stage]
        while queue:
            m = queue.pop(0)
            for t in sorted(graph[m]):
                if is_cli(t) and t not in path:
                    path[t] = [*path[m], t]
                    if t in stages:
                        bad.append(" -> ".join(path[t]))
                    else:
                        queue.append(t)
    assert not bad, "stage modules reach other stage modules:\n" + "\n".join(bad)


def test_no_import_cycle_in_the_cli() -> None:
    graph = {m: {t for t in ts if is_cli(t)} for m, ts in imports().items() if is_cli(m)}
    found = cycles(graph)
    assert not found, "import cycles in artic.cli:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_cli_is_under_4000_lines() -> None:
    lines = {
        p.name: len(p.read_text(encoding="utf-8").splitlines()) for p in PACKAGE.glob("cli/*.py")
    }
    total = sum(lines.values())
    biggest = sorted(lines.items(), key=lambda kv: -kv[1])[:5]
    assert total < CLI_MAX_LINES, f"src/artic/cli/*.py: {total} lines (largest: {biggest})"
