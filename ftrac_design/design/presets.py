"""Where the preset design files live, found in one place.

The presets are the checkout's ``models/*.toml`` (``ftrac_2005``, ``ftrac_mini``,
``nine_bead``, …). Every room that needs one asks :func:`preset_path` rather than walking up
from its own file, so moving the presets (into the package, for a wheel) changes this module
only.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError

#: the folder holding the preset design files
PRESETS_DIR = Path(__file__).resolve().parents[2] / "models"


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
    stem = name[:-5] if name.endswith(".toml") else name
    path = PRESETS_DIR / f"{stem}.toml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in PRESETS_DIR.glob("*.toml"))) or "none found"
        raise InputError(path, None, f"a preset design ({known})")
    return path
