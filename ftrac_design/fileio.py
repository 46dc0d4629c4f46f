"""Atomic file and directory writes (a failed run never leaves half-written output) and the
strict JSON / JSON Lines reading every input file shares (finite numbers only; errors name
the file and line).

Every temporary name (:func:`temporary_file`, :func:`temporary_directory`) gets the mode a
plain ``open`` / ``mkdir`` would give it under the user's umask (0644 / 0755 under 022),
not ``mkstemp``'s 0600 or ``mkdtemp``'s 0700: what is renamed into place is readable by
whoever may read the rest of the output (a colleague on a shared drive, a web server).
"""

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


def current_umask() -> int:
    """The process's umask (e.g. ``0o022``).

    Read from ``/proc/self/status`` where the kernel reports it, so no other thread sees a
    changed umask; elsewhere set and restored at once.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o077)
    os.umask(mask)
    return mask


def plain_mode(path: str | Path, directory: bool = False) -> None:
    """Give ``path`` the mode ``open`` (0666) or ``mkdir`` (0777) would have given it under the
    current umask."""
    os.chmod(path, (0o777 if directory else 0o666) & ~current_umask())


def temporary_file(final: str | Path, suffix: str | None = None) -> tuple[int, Path]:
    """A new hidden temporary file beside ``final`` with a plain file's mode (see the module).

    Parameters
    ----------
    final : the path the file will be renamed to; its folder must exist.
    suffix : the temporary name's suffix (default: ``final``'s, so writers that go by the
        suffix pick the right format).

    Returns
    -------
    (fd, path) : an open descriptor (the caller closes it) and the temporary path.
    """
    final = Path(final)
    sfx = final.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=f".{final.stem if suffix is None else final.name}.", suffix=sfx, dir=final.parent)
    try:
        os.fchmod(fd, 0o666 & ~current_umask())
    except BaseException:
        os.close(fd)
        os.unlink(tmp)
        raise
    return fd, Path(tmp)


def temporary_directory(final: str | Path) -> Path:
    """A new hidden temporary directory beside ``final`` with a plain directory's mode."""
    final = Path(final)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent))
    try:
        plain_mode(tmp, directory=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return tmp


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` via a temporary file in the same folder, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temporary_file(path, suffix=".tmp")
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
    fd, tmp = temporary_file(path)
    os.close(fd)
    try:
        yield tmp
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
    tmp = temporary_directory(final)
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
