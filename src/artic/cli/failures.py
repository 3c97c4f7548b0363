"""How the `artic` command fails: exit codes and one line on stderr, never a traceback.

Bad input (`InputError`, and Typer's usage errors) exits 2 with one line naming the field
or file; Ctrl-C 130, SIGTERM 143 (`Interrupted`); an internal failure exits 1 with one
line saying where its traceback was written (docs/architecture.md, "Guarantees").
"""

from __future__ import annotations

import functools
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import typer
from typer.core import TyperGroup

F = TypeVar("F", bound=Callable[..., Any])


class OneLineErrors(TyperGroup):
    """Usage errors (an unknown option, a value of the wrong type or out of an option's
    range, a missing argument) as one line on stderr, exit 2, like every other bad input."""

    def main(
        self,
        args: Any = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        windows_expand_args: bool = True,
        **extra: Any,
    ) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, windows_expand_args, **extra)
        try:
            rv = super().main(args, prog_name, complete_var, False, windows_expand_args, **extra)
        except typer.TyperException as err:
            if type(err).__name__ == "NoArgsIsHelpError":  # `artic` alone: the help, as before
                return super().main(args, prog_name, complete_var, True, windows_expand_args)
            message = err.format_message() if hasattr(err, "format_message") else str(err)
            lines = [ln.strip() for ln in str(message).splitlines() if ln.strip()]
            typer.echo(f"error: {' '.join(lines)}", err=True)
            sys.exit(int(getattr(err, "exit_code", 2)))
        except typer.Abort:
            typer.echo("aborted", err=True)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)


def internal_log_path() -> Path:
    """Where an internal error not raised inside a stage's work folder leaves its
    traceback: `$TMPDIR/artic-<pid>.log` (docs/architecture.md, "Errors")."""
    import os
    import tempfile

    return Path(tempfile.gettempdir()) / f"artic-{os.getpid()}.log"


def _write_traceback(err: BaseException) -> Path | None:
    """Append the traceback of `err` (with the command line) to `internal_log_path()`."""
    import traceback
    from datetime import UTC, datetime

    path = internal_log_path()
    text = "".join(traceback.format_exception(type(err), err, err.__traceback__))
    stamp = datetime.now(UTC).isoformat(timespec="seconds")
    try:
        with path.open("a", encoding="utf-8") as f:
            f.write(f"{stamp} artic {' '.join(sys.argv[1:])}\n{text}\n")
    except OSError:
        return None
    return path


def _one_line(text: str) -> str:
    lines = [ln.strip() for ln in str(text).splitlines() if ln.strip()]
    return " ".join(lines) if lines else ""


def handle_errors(fn: F) -> F:
    """Map failures to exit codes: bad input 2 (one line), Ctrl-C 130, SIGTERM 143, internal 1.

    Every internal failure prints one line, `internal error: ... (traceback in PATH)`:
    stage commands and segment/build-hierarchy/infer-hierarchy name their work folder's
    `artic.log`; any other unexpected exception (raised before a work folder exists, or
    by predict/pipeline) is written to `$TMPDIR/artic-<pid>.log`. Never a traceback on
    stderr."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from artic.cli.stage_runner import InternalError
        from artic.errors import InputError, Interrupted

        try:
            return fn(*args, **kwargs)
        except InputError as err:
            typer.echo(f"error: {_one_line(str(err))}", err=True)
            raise typer.Exit(2) from None
        except Interrupted as err:
            typer.echo(_one_line(str(err)), err=True)
            raise typer.Exit(err.exit_code) from None
        except KeyboardInterrupt:
            typer.echo("interrupted", err=True)
            raise typer.Exit(130) from None
        except InternalError as err:
            where = f" (traceback in {err.log_path})" if err.log_path else ""
            typer.echo(f"internal error: {_one_line(str(err))}{where}", err=True)
            raise typer.Exit(1) from None
        except (typer.Exit, typer.Abort, typer.TyperException):
            raise
        except Exception as err:
            log_path = _write_traceback(err)
            where = f" (traceback in {log_path})" if log_path else ""
            message = _one_line(f"{type(err).__name__}: {err}")
            typer.echo(f"internal error: {message}{where}", err=True)
            raise typer.Exit(1) from None

    return wrapper  # type: ignore[return-value]


class NoTracebacks(logging.Filter):
    """Keeps tracebacks off the terminal: a record carrying one (exc_info, or a
    formatted traceback in its message) goes only to the log files."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info or record.exc_text:
            return False
        return "Traceback (most recent call last)" not in record.getMessage()
