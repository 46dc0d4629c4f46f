"""Errors that the command line turns into exit codes (see SPEC §5)."""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad user input: a design, features, observation file or argument.

    The command line prints :meth:`for_command_line` as one line on stderr and exits 2. The
    message always names the file, the key and what was expected.

    Parameters
    ----------
    file : path or None
        The file at fault (None: an argument).
    key : str or None
        The key inside the file (``"wires.diameter"``), or None.
    expected : str
        What was expected, in words (``"a number, got 'x'"``).
    parameter : str or None
        When the fault is in a function's argument rather than in a file's key: the argument's
        name (``"output"``, ``"objective"``). The library names the argument; the command line
        names its flag (``--output``), which follows the argument's name.
    """

    def __init__(self, file: str | Path | None, key: str | None, expected: str, *, parameter: str | None = None):
        self.file = str(file) if file is not None else None
        self.key = key if key is not None else parameter
        self.parameter = parameter
        self.expected = expected
        super().__init__(self._message(self.key))

    def _message(self, key: str | None) -> str:
        where = self.file or "<input>"
        if key:
            where += f": {key}"
        return f"{where}: {self.expected}"

    def for_command_line(self) -> str:
        """The message with an argument's name given as the command line's flag (``--output``)."""
        if self.parameter is None:
            return str(self)
        return self._message("--" + self.parameter.replace("_", "-"))


class GoalError(Exception):
    """The work ran but did not reach its goal (design-rule violation, pose not found).

    The command line exits 1.
    """
