"""Entry point: ``ftrac-design COMMAND …`` with SPEC §5's exit codes.

0 success; 1 the work ran but failed its goal; 2 bad input or usage — reported as one line
on stderr that names the file, the key and what was expected, never a traceback.
Each command lives in its own module and imports its heavy dependencies (CadQuery, the
solver) only when it runs, so ``--help`` and the solver stay fast.
"""

from __future__ import annotations

import importlib
import sys

import click

from ..errors import GoalError, InputError

#: command name → module under ftrac_design.cli that defines ``command``
COMMANDS = {
    "build": "build",
    "check": "check",
    "drawings": "drawings",
    "solve": "solve",
    "analyze": "analyze",
    "compare": "compare",
    "radiograph": "radiograph",
    "track": "track",
    "optimize": "optimize",
    "reconstruct": "reconstruct",
    "report": "report",
    "distortion": "distortion",
    "presets": "presets",
    "serve": "serve",
    "push": "push",
    "export": "export",
    "gcode": "gcode",
    "coupon": "coupon",
    "train-detector": "train_detector",
}


class _LazyGroup(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return [name for name in COMMANDS if self._load(name) is not None]

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        return self._load(name)

    @staticmethod
    def _load(name: str) -> click.Command | None:
        mod = COMMANDS.get(name)
        if mod is None:
            return None
        try:
            return importlib.import_module(f"ftrac_design.cli.{mod}").command
        except ModuleNotFoundError as exc:
            if exc.name == f"ftrac_design.cli.{mod}":
                return None
            raise


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="ftrac_design")
def cli() -> None:
    """Design, manufacture and score FTRAC radiographic fiducials (Jain et al. 2005)."""


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (also used by the console script)."""
    try:
        rv = cli.main(args=argv, prog_name="ftrac-design", standalone_mode=False)
    except click.exceptions.NoArgsIsHelpError as exc:  # bare `ftrac-design`: help, not an error
        click.echo(exc.ctx.get_help() if exc.ctx else str(exc))
        return 0
    except click.UsageError as exc:
        cmd = exc.ctx.command_path if exc.ctx else "ftrac-design"
        click.echo(f"{cmd}: {_one_line(exc.format_message())} (see --help)", err=True)
        return 2
    except InputError as exc:
        click.echo(f"error: {_one_line(exc.for_command_line())}", err=True)
        return 2
    except GoalError as exc:
        click.echo(f"failed: {_one_line(str(exc))}", err=True)
        return 1
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 130
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.ClickException as exc:
        click.echo(f"error: {_one_line(exc.format_message())}", err=True)
        return exc.exit_code
    return rv if isinstance(rv, int) else 0


def entry() -> None:
    """Console-script wrapper: exit with :func:`main`'s code."""
    sys.exit(main())


if __name__ == "__main__":
    entry()
