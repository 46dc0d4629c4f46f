"""Draw the rooms of ``ftrac_design`` and the one-way flow of their imports from the layers
contract in pyproject.toml (``[[tool.importlinter.contracts]]`` of type ``layers``), into
docs/img/layers.png.

Run it after changing the contract::

    .venv/bin/python docs/gen_layers.py

The picture carries the layers it was drawn from in its PNG metadata (``Description``), so
tests/test_docs.py can tell when the contract has changed and the picture has not.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "img" / "layers.png"
#: box colours: the entry points green, the one room that may import CadQuery amber, the rest blue
COLOURS = {"demo": "#d9ead3", "cli": "#d9ead3", "cad": "#f4d6a0"}


def contract_layers(pyproject: Path = ROOT / "pyproject.toml") -> list[list[str]]:
    """The layers of the import contract, top (may import everything below) to bottom.

    Parameters
    ----------
    pyproject : pathlib.Path
        The project file holding ``[tool.importlinter]``.

    Returns
    -------
    list of list of str
        One list of room names per layer; rooms written ``a | b`` share a layer and do not
        import each other.
    """
    conf = tomllib.loads(pyproject.read_text(encoding="utf-8"))
    for contract in conf["tool"]["importlinter"]["contracts"]:
        if contract.get("type") == "layers":
            return [[room.strip() for room in layer.split("|")] for layer in contract["layers"]]
    raise ValueError(f"{pyproject}: no layers contract in [tool.importlinter]")


def cad_only_modules(pyproject: Path = ROOT / "pyproject.toml") -> list[str]:
    """The third-party modules that only ``cad`` may import (the forbidden contract)."""
    conf = tomllib.loads(pyproject.read_text(encoding="utf-8"))
    for contract in conf["tool"]["importlinter"]["contracts"]:
        if contract.get("type") == "forbidden":
            return list(contract["forbidden_modules"])
    return []


def describe(layers: list[list[str]]) -> str:
    """The layers as one line, top to bottom (the picture's metadata, compared by the tests)."""
    return " > ".join(" | ".join(layer) for layer in layers)


def draw(layers: list[list[str]], out: Path = OUT) -> Path:
    """Draw ``layers`` as stacked bands of room boxes with the import direction, into ``out``.

    Parameters
    ----------
    layers : list of list of str
        As :func:`contract_layers` returns them.
    out : pathlib.Path
        The PNG to write.

    Returns
    -------
    pathlib.Path
        ``out``.
    """
    n = len(layers)
    row_h, width = 0.62, 7.2
    fig, ax = plt.subplots(figsize=(8.4, 0.5 + row_h * n))
    ax.set_xlim(0, 10.4)
    ax.set_ylim(-0.4, n * row_h + 0.1)
    ax.axis("off")
    heavy = cad_only_modules()
    for i, layer in enumerate(layers):
        y = (n - 1 - i) * row_h
        box_w = (width - 0.2 * (len(layer) - 1)) / len(layer)
        for j, room in enumerate(layer):
            x = 0.3 + j * (box_w + 0.2)
            colour = COLOURS.get(room, "#cfe2f3")
            ax.add_patch(
                FancyBboxPatch(
                    (x, y + 0.08),
                    box_w,
                    row_h - 0.2,
                    boxstyle="round,pad=0.02,rounding_size=0.08",
                    fc=colour,
                    ec="#345",
                    lw=1.0,
                )
            )
            ax.text(
                x + box_w / 2, y + row_h / 2 - 0.02, room, ha="center", va="center", fontsize=10, family="monospace"
            )
        if len(layer) > 1:
            ax.text(
                0.3 + width + 0.15,
                y + row_h / 2 - 0.02,
                "side by side:\nno imports between",
                fontsize=7,
                va="center",
                color="#555",
            )
    ax.add_patch(
        FancyArrowPatch(
            (10.25, n * row_h - 0.15), (10.25, 0.05), arrowstyle="-|>", mutation_scale=18, lw=1.6, color="#a33"
        )
    )
    ax.text(
        10.05, n * row_h / 2, "imports flow down only", rotation=90, ha="center", va="center", fontsize=9, color="#a33"
    )
    note = f"only cad imports {' and '.join(heavy)}" if heavy else ""
    ax.text(
        0.3,
        -0.25,
        f"The layers contract in pyproject.toml (import-linter, run by make test); {note}.",
        fontsize=8,
        color="#333",
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight", metadata={"Description": describe(layers)})
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(draw(contract_layers()))
