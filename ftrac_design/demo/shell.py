"""How the demo shows what it does as a user would see it: the command line run in this
process with its output captured, the command as typed, and paths relative to the working
directory."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path


def relative(path: str | Path) -> Path:
    """``path`` relative to the working directory when it lies inside it, else as given.

    Parameters
    ----------
    path : str or pathlib.Path
        Any path.

    Returns
    -------
    pathlib.Path
        The shorter form a user reads.
    """
    path = Path(path)
    cwd = Path.cwd()
    if path.is_absolute() and path.is_relative_to(cwd):
        return path.relative_to(cwd)
    return path


def run_cli(args: list[str | Path]) -> tuple[int, str, str]:
    """``ftrac-design ARGS`` through :func:`ftrac_design.cli.main.main`, its stdout and stderr
    captured.

    Parameters
    ----------
    args : list of str or pathlib.Path
        The command and its arguments.

    Returns
    -------
    tuple
        (exit code, stdout, stderr).
    """
    from ..cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in args])
    return rc, out.getvalue(), err.getvalue()


def command_line(args: list[str | Path]) -> str:
    """How a user types ``args`` (as :func:`run_cli` takes them): ``$ ftrac-design …``, each
    path relative where it can be (:func:`relative`); returns the line."""
    return "$ ftrac-design " + " ".join(str(relative(a)) if isinstance(a, Path) else str(a) for a in args)
