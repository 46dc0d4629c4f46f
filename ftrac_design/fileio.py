"""Atomic file and directory writes (a failed run never leaves half-written output) and the
strict JSON / JSON Lines reading every input file shares (finite numbers only; errors name
the file and line)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterator

from .errors import InputError


def sha256_file(path: str | Path) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` via a temporary file in the same folder, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


@contextlib.contextmanager
def atomic_file(path: str | Path) -> Iterator[Path]:
    """Yield a temporary name beside ``path`` (same suffix) for a writer that needs a file
    name (e.g. matplotlib); on success it is renamed to ``path``, on failure removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_json_atomic(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented UTF-8 JSON, atomically."""
    return write_text_atomic(path, json.dumps(obj, indent=2, allow_nan=False) + "\n")


@contextlib.contextmanager
def atomic_directory(final: str | Path) -> Iterator[Path]:
    """Yield a temporary sibling directory; on success it replaces ``final`` whole.

    On any exception the temporary directory is removed and ``final`` is left as it was
    (absent, or holding the previous complete build).
    """
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if final.exists():
        old = final.with_name(f".{final.name}.old-{os.getpid()}")
        os.replace(final, old)
    os.replace(tmp, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def json_format_is(path: str | Path, fmt: str) -> bool:
    """Whether ``path`` is a readable JSON object whose ``"format"`` is ``fmt``."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8")).get("format") == fmt
    except (OSError, ValueError, AttributeError):
        return False


def check_output_dir(
    out_dir: str | Path, earlier: str, is_earlier: Callable[[Path], bool], parameter: str | None = "output"
) -> None:
    """Refuse an output directory that :func:`atomic_directory` must not replace.

    Parameters
    ----------
    out_dir : path
        Where a command will write its whole output (replaced at once on success).
    earlier : str
        What an earlier output of the same command is called in the message ("an earlier build's
        output").
    is_earlier : callable
        Given the directory, whether it holds such an earlier output (it is then replaced).
    parameter : str or None
        The argument the error names (the command line shows it as its flag), or None.

    Raises
    ------
    InputError
        When ``out_dir`` is a file, or a directory holding anything else.
    """
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(out_dir, None, "a directory (a file of that name exists)", parameter=parameter)
    if out_dir.is_dir() and any(out_dir.iterdir()) and not is_earlier(out_dir):
        raise InputError(
            out_dir,
            None,
            f"a new or empty directory, or {earlier} (this one holds other files; it would be replaced whole)",
            parameter=parameter,
        )


def _reject_constant(name: str) -> float:
    raise ValueError(f"finite numbers (JSON has no {name})")


def read_text_input(path: str | Path) -> str:
    """The UTF-8 text of an input file; InputError (exit 2) when missing or unreadable."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, None, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, None, f"a readable UTF-8 file ({exc})") from None


def parse_json(text: str, origin: str | Path, expected: str = "valid JSON") -> Any:
    """``json.loads`` that refuses NaN/Infinity; InputError naming ``origin`` on failure."""
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise InputError(origin, None, f"{expected} ({exc.msg} at line {exc.lineno})") from None
    except ValueError as exc:
        raise InputError(origin, None, str(exc)) from None


def json_lines(path: str | Path, text: str | None = None) -> Iterator[tuple[str, Any]]:
    """(origin ``"file:line"``, parsed value) for each non-blank line of a JSON Lines file."""
    text = read_text_input(path) if text is None else text
    for i, line in enumerate(text.splitlines(), 1):
        if line.strip():
            origin = f"{path}:{i}"
            yield origin, parse_json(line, origin, "one JSON object per line")


def write_output_text(output: str | Path, text: str):
    """Write a command's result ``text`` to ``output`` atomically, or to stdout when it is
    ``-``; returns the stream the command's messages go to (stderr when stdout holds the
    result). An unwritable path is an InputError (exit 2)."""
    import sys

    if str(output) == "-":
        sys.stdout.write(text)
        return sys.stderr
    try:
        write_text_atomic(output, text)
    except OSError as exc:
        raise InputError(output, None, f"a writable output path ({exc.strerror})") from None
    return sys.stdout
