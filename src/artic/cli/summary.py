"""One Rich summary per stage run, printed on stdout."""

from __future__ import annotations

import logging

from rich.console import Console
from rich.table import Table

from artic.cli.stage_runner import Result


def print_result(command: str, result: Result) -> None:
    """The run's statistics as a table; nothing under --quiet."""
    if not logging.getLogger().isEnabledFor(logging.INFO):
        return
    console = Console()
    if result.status == "skipped":
        console.print(
            f"[green]{command}[/]: {result.out} is up to date (skipped; --force redoes it)"
        )
        return
    if result.status == "partial":
        console.print(f"[yellow]{command}[/]: {result.message}")
        return
    assert result.manifest is not None
    table = Table(title=f"{command} -> {result.out}", show_header=False, title_justify="left")
    for key, value in result.manifest.stats.items():
        table.add_row(key, f"{value:,.1f}" if isinstance(value, float) else str(value))
    table.add_row("wall time", f"{result.manifest.wall_time_s:.1f} s")
    table.add_row("manifest", str(result.out / "manifest.json"))
    console.print(table)
