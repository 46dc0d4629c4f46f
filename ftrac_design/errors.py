"""Errors that the command line turns into exit codes (see SPEC §5)."""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType


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


class MissingDependencyError(InputError):
    """An optional package that the asked-for work needs is not installed (exit 2).

    The package's optional dependencies are grouped by the room that needs them (the *extras*
    of ``pyproject.toml``: ``cad``, ``dicom``, ``optimize``, …); ``make`` installs all of them.
    The message names the missing module, what needed it and the one command that installs it.

    Parameters
    ----------
    module : str
        The import name that failed (``"cma"``).
    extra : str
        The extra of ``ftrac_design`` that provides it (``"optimize"``).
    purpose : str
        What needed it, in words (``"the CMA-ES design search"``).
    """

    def __init__(self, module: str, extra: str, purpose: str):
        self.module = module
        self.extra = extra
        self.purpose = purpose
        super().__init__(None, None, "")

    def _message(self, key: str | None) -> str:
        return (
            f"{self.purpose} needs the Python package {self.module!r}, which is not installed: "
            f"pip install 'ftrac_design[{self.extra}]'"
        )


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Import an optional dependency, or raise :class:`MissingDependencyError`.

    Parameters
    ----------
    module : str
        The module to import (``"pymoo.algorithms.moo.nsga2"``); the message names its top-level
        package.
    extra : str
        The ``ftrac_design`` extra that installs it.
    purpose : str
        What needs it, in words, for the message.

    Returns
    -------
    module
        The imported module.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".")[0]
        missing = (exc.name or top).split(".")[0]
        if missing != top:  # the package is there but one of its own imports failed: not ours to hide
            raise
        raise MissingDependencyError(top, extra, purpose) from None
