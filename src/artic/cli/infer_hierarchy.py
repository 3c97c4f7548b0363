"""`artic segment`, `artic build-hierarchy` and `artic infer-hierarchy` from the command
line: the commands themselves (one scan in, one output folder out) are
`artic.hierarchy.commands` (`main.py` imports them from there); here, running one of them
with the CLI's failure mapping and printing its Rich summary.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import ParamSpec

import numpy as np

from artic.cli.stage_runner import InternalError
from artic.hierarchy.commands import CommandFailed, CommandResult, uncertain_front
from artic.objects.tree import MOTION_TYPES

log = logging.getLogger("artic")

P = ParamSpec("P")


def run(command: Callable[P, CommandResult], *args: P.args, **kwargs: P.kwargs) -> None:
    """Run one of the commands and print its summary; a failure while it wrote its output
    folder is an internal error (exit 1) naming the folder's log."""
    try:
        result = command(*args, **kwargs)
    except CommandFailed as err:
        raise InternalError(str(err), err.log_path) from err
    print_summary(result)


def print_summary(result: CommandResult) -> None:
    """Parts, joints and timings as Rich tables, the models used, then the output folder
    (not under -q; a debug model's warning is always shown, on stderr)."""
    for choice in result.models:
        if choice.warning:
            log.warning("%s: %s", result.command, choice.warning)
    yaw = result.yaw
    if yaw is not None and (warning := uncertain_front(yaw)):
        log.warning("%s: %s", result.command, warning)
    if not logging.getLogger().isEnabledFor(logging.INFO):
        return
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(f"[bold]{result.command}[/]: {result.points:,} points, {result.num_parts} parts")
    h = result.hierarchy
    if h is not None:
        tree = h.tree
        table = Table(title=f"kinematic tree (root: part {tree.root})", title_justify="left")
        for column in ("edge", "joint", "motion", "p exist", "p dir", "axis"):
            table.add_column(column)
        for k, ((a, b), joint_type) in enumerate(zip(tree.edges, tree.joint_types, strict=True)):
            axis = None if tree.axes is None else tree.axes[k]
            exists, direction = h.edge_exists[k], h.edge_direction[k]
            table.add_row(
                f"{a} -> {b}",
                joint_type,
                MOTION_TYPES[tree.motion_types[b]],
                "-" if np.isnan(exists) else f"{exists:.2f}",
                "-" if np.isnan(direction) else f"{direction:.2f}",
                "-" if axis is None else ",".join(f"{v:+.2f}" for v in axis.direction),
            )
        if tree.edges:
            console.print(table)
    if yaw is not None:
        console.print(
            f"scan yaw: {yaw.yaw_deg:+.1f} deg (plane confidence {yaw.plane_confidence:.2f}, "
            f"front confidence {yaw.front_confidence:.2f}); outputs in the scan's frame"
        )
    steps = ", ".join(f"{k} {v:.3f} s" for k, v in result.timings.items())
    console.print(f"timings: {steps}")
    for choice in result.models:
        console.print(f"{choice.kind}: {choice.describe()}")
    console.print(f"output: {result.out}")
