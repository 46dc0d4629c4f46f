"""Where the preset design files and search spaces live, found in one place.

The presets are the design files in ``models/`` (``ftrac_2005``, ``ftrac_mini``, ``nine_bead``,
…; search spaces in ``models/spaces/``), shipped inside the package as ``ftrac_design.presets``
and read through :mod:`importlib.resources`, so an installed wheel has them as a checkout does. Every
room that needs one asks this module rather than walking up from its own file, and every
command that takes a design path also takes a preset's name (:func:`resolve_design`).
"""

from __future__ import annotations

import os
import tomllib
from importlib.resources import files
from pathlib import Path

from ..errors import InputError

#: the folder holding the preset design files (package data; on disk for any ordinary install)
PRESETS_DIR = Path(os.fspath(files("ftrac_design.presets")))
#: the folder holding the shipped search spaces (``ftrac-design optimize --space``)
SPACES_DIR = PRESETS_DIR / "spaces"


def _names(folder: Path) -> list[str]:
    return sorted(p.stem for p in folder.glob("*.toml"))


def preset_names() -> list[str]:
    """The names of the preset designs, sorted.

    Returns
    -------
    list of str
        The file stems in :data:`PRESETS_DIR` (``["ftrac_2005", "ftrac_mini", …]``).
    """
    return _names(PRESETS_DIR)


def space_names() -> list[str]:
    """The names of the shipped search spaces, sorted.

    Returns
    -------
    list of str
        The file stems in :data:`SPACES_DIR` (``["ftrac_2005_ellipses", …]``).
    """
    return _names(SPACES_DIR)


def known_presets() -> str:
    """The preset names as one comma-separated phrase for error messages.

    Returns
    -------
    str
        ``"ftrac_2005, ftrac_mini, …"``, or ``"none found"``.
    """
    return ", ".join(preset_names()) or "none found"


def known_spaces() -> str:
    """The shipped search-space names as one comma-separated phrase for error messages.

    Returns
    -------
    str
        ``"ftrac_2005_ellipses, …"``, or ``"none found"``.
    """
    return ", ".join(space_names()) or "none found"


def _stem(name: str) -> str:
    return name[:-5] if name.endswith(".toml") else name


def _shipped(folder: Path, name: str, what: str, known) -> Path:
    path = folder / f"{_stem(name)}.toml"
    if not path.is_file():
        raise InputError(path, None, f"{what} ({known()})")
    return path


def preset_path(name: str) -> Path:
    """The design file of the preset ``name`` (``"ftrac_2005"``; a ``.toml`` suffix is allowed).

    Parameters
    ----------
    name : str
        The preset's name, the file's stem in :data:`PRESETS_DIR`.

    Returns
    -------
    pathlib.Path
        Its path. Raises :class:`InputError` naming the presets there are when it does not exist.
    """
    return _shipped(PRESETS_DIR, name, "a preset design", known_presets)


def space_path(name: str) -> Path:
    """The file of the shipped search space ``name`` (``"ftrac_mini_layout"``; ``.toml`` allowed).

    Parameters
    ----------
    name : str
        The space's name, the file's stem in :data:`SPACES_DIR`.

    Returns
    -------
    pathlib.Path
        Its path; :class:`InputError` naming the shipped spaces when there is no such space.
    """
    return _shipped(SPACES_DIR, name, "a shipped search space", known_spaces)


def _resolve(source: str | Path, folder: Path) -> Path:
    path = Path(source)
    if path.is_file() or path.parent != Path(".") or not path.name:
        return path
    candidate = folder / f"{_stem(path.name)}.toml"
    return candidate if candidate.is_file() else path


def resolve_design(source: str | Path) -> Path:
    """The design file that ``source`` names: a path, or a preset's name.

    A file that exists is taken as it is, so a local ``ftrac_2005.toml`` wins over the preset
    of that name; otherwise a bare name (no directory part, with or without ``.toml``) that
    names a preset is that preset's file (a folder ``ftrac_2005/`` in the working directory,
    such as a build, does not hide the preset).

    Parameters
    ----------
    source : str or pathlib.Path
        What the user gave: ``"ftrac_2005"``, ``"nine_bead.toml"`` or ``"my/design.toml"``.

    Returns
    -------
    pathlib.Path
        The existing file, the preset's file, or ``source`` unchanged (the reader then reports
        it as not found, with the preset names: :func:`known_presets`).
    """
    return _resolve(source, PRESETS_DIR)


def resolve_space(source: str | Path) -> Path:
    """The search-space file that ``source`` names: a path, or a shipped space's name.

    Parameters
    ----------
    source : str or pathlib.Path
        ``"ftrac_mini_layout"`` or a path to a space TOML.

    Returns
    -------
    pathlib.Path
        The existing file, the shipped space's file, or ``source`` unchanged (as
        :func:`resolve_design`).
    """
    return _resolve(source, SPACES_DIR)


def _header_comment(text: str) -> str:
    """The file's leading comment block as one line, up to its first sentence's end."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        body = line.lstrip("#").strip()
        if not body:  # an empty comment line ends the first paragraph
            break
        lines.append(body)
    words = " ".join(lines)
    end = words.find(". ")
    return words[: end + 1] if end >= 0 else words


def describe(path: str | Path, width: int = 110) -> str:
    """A one-line description of a preset design or search-space file.

    The design's own ``description`` key where it has one, else the first sentence of the
    file's header comment; shortened to ``width`` characters.

    Parameters
    ----------
    path : str or pathlib.Path
        A TOML file (one of :data:`PRESETS_DIR` or :data:`SPACES_DIR`).
    width : int
        The longest line returned; longer ones end in "…".

    Returns
    -------
    str
        The description ("" when the file has neither).
    """
    text = Path(path).read_text(encoding="utf-8")
    try:
        desc = tomllib.loads(text).get("description")
    except tomllib.TOMLDecodeError:
        desc = None
    line = " ".join(str(desc).split()) if isinstance(desc, str) and desc.strip() else _header_comment(text)
    return line if len(line) <= width else line[: width - 1].rstrip() + "…"
