"""Errors that the command line turns into exit codes (see SPEC §5)."""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad user input: a design, features, observation file or argument.

    The command line prints ``str(err)`` as one line on stderr and exits 2. The message
    always names the file, the key and what was expected.
    """

    def __init__(self, file: str | Path | None, key: str | None, expected: str):
        self.file = str(file) if file is not None else None
        self.key = key
        self.expected = expected
        where = self.file or "<input>"
        if key:
            where += f": {key}"
        super().__init__(f"{where}: {expected}")


class GoalError(Exception):
    """The work ran but did not reach its goal (design-rule violation, pose not found).

    The command line exits 1.
    """
