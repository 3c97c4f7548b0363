"""The README's commands run verbatim, as far as a test can run them: every stage command
composes and validates its config (`--cfg`, as the run does), every pipeline resolves
(`--dry-run`), and every other command knows each option the README gives it."""

from __future__ import annotations

import re
import shlex
from pathlib import Path
from typing import Any

import pytest
import typer

from artic.cli.main import app
from artic.cli.registry import stage_entries
from cli_runner import run_cli

README = Path(__file__).parents[1] / "README.md"


def readme_commands() -> list[str]:
    """`artic ...` of the README: the first cell of its tables' rows and the lines of its
    code blocks (comments after `#` dropped); `[optional]` parts removed."""
    text = README.read_text()
    found = re.findall(r"^\| `(artic [^`]+)`", text, flags=re.M)  # a table's first cell
    blocks = re.findall(r"```\n(.*?)```", text, flags=re.S)
    found += [
        line.split(" #")[0] for b in blocks for line in b.splitlines() if line.startswith("artic ")
    ]
    commands = []
    for command in found:
        command = re.sub(r"\s*\[[^\]]*\]", "", command).strip()
        if command not in commands and not command.startswith("artic --"):
            commands.append(command)
    return commands


def _stage_words() -> dict[tuple[str, ...], str]:
    return {tuple(e.command): e.name for e in stage_entries().values()}


def _click_command(words: list[str]) -> Any:
    command: Any = typer.main.get_command(app)
    for word in words:
        assert hasattr(command, "commands"), words
        command = command.commands[word]
    return command


COMMANDS = readme_commands()


def test_the_readme_has_commands():
    assert len(COMMANDS) >= 30
    assert any(c.startswith("artic predict") for c in COMMANDS)


@pytest.mark.parametrize("command", COMMANDS, ids=[" ".join(c.split()[1:3]) for c in COMMANDS])
def test_readme_command(command: str):
    args = shlex.split(command)[1:]
    stages = _stage_words()
    words = next(
        (list(w) for w in sorted(stages, key=len, reverse=True) if tuple(args[: len(w)]) == w),
        None,
    )
    if words is not None:  # a stage: its config composes and validates
        extra = [] if "--cfg" in args else ["--cfg"]
        code, _, err = run_cli(*args, *extra)
        assert code == 0, f"{command}: {err}"
    elif args[0] in ("pipeline", "bootstrap"):
        extra = [] if "--status" in args else ["--dry-run"]
        code, _, err = run_cli(*args, *extra)
        assert code == 0, f"{command}: {err}"
    elif args[0] == "models":
        code, _, err = run_cli(*args)
        assert code == 0, f"{command}: {err}"
    else:  # a command on a user's file: every option it is given exists
        click_command = _click_command([a for a in args[:1]])
        names = {o for p in click_command.params for o in getattr(p, "opts", [])}
        for arg in args[1:]:
            if arg.startswith("--"):
                assert arg in names, f"{command}: {arg} is not an option of artic {args[0]}"
