"""``ftrac-design presets [--paths]``: the preset designs and search spaces shipped with the
package, one line each (:mod:`ftrac_design.design.presets`)."""

from __future__ import annotations

import click

from .options import flag_option


@click.command("presets")
@flag_option("--paths", help="also print each file's path (to copy a preset as the start of a new design)")
def command(paths: bool) -> int:
    """List the preset designs and the shipped search spaces, each with a short description.

    A preset's name works wherever a design file does (`ftrac-design build ftrac_2005`,
    `analyze ftrac_mini`, `check nine_bead`), a space's name wherever `--space` takes a file.
    """
    from ..design.presets import PRESETS_DIR, SPACES_DIR, describe, preset_names, space_names

    for title, folder, names in (
        ("designs (build NAME, analyze NAME, check NAME, …)", PRESETS_DIR, preset_names()),
        ("search spaces (optimize DESIGN --space NAME)", SPACES_DIR, space_names()),
    ):
        click.echo(f"{title}:")
        width = max((len(n) for n in names), default=0)
        for name in names:
            path = folder / f"{name}.toml"
            click.echo(f"  {name:<{width}}  {describe(path)}")
            if paths:
                click.echo(f"  {'':<{width}}  {path}")
    return 0
