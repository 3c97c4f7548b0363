"""The two kinds of failure artic distinguishes.

`InputError` is the user's to fix (a missing file, a value out of range): the CLI prints
its one-line message on stderr and exits with code 2, never a traceback. Anything else
is an internal failure: exit code 1 and the traceback in the stage's log file.
"""

from __future__ import annotations


class InputError(Exception):
    """Bad input: a file, path or config field that is missing, malformed or out of range.

    The message is one line naming the file or field and what was expected.
    """

    exit_code = 2


class Interrupted(Exception):
    """Work stopped by the user (Ctrl-C: exit code 130) or by SIGTERM (143, as a shell
    reports a process ended by that signal); finished chunks are kept for a resume."""

    def __init__(self, message: str, exit_code: int = 130) -> None:
        super().__init__(message)
        self.exit_code = exit_code
