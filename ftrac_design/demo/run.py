"""The demo's runner: every step in order, each printed as it finishes; a step that needs an
optional extra which is not installed is skipped with one line naming the extra, and the
demo goes on.

A step that needs an earlier one (the report needs the build) is skipped when that one was,
with the reason. The demo ends with the list of what it skipped; it exits 0 then too, 2 on bad
input and 1 when a step failed its goal.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, TextIO

from ..errors import GoalError, InputError, MissingDependencyError


@dataclass(frozen=True)
class Step:
    """One step of the demo.

    Attributes
    ----------
    name : str
        What the step shows, for the skip lines (``"the design search"``).
    run : callable
        Runs the step; returns the text to print.
    needs : tuple of str
        The names of earlier steps whose output this one reads.
    """

    name: str
    run: Callable[[], str]
    needs: tuple[str, ...] = ()


@dataclass
class Outcome:
    """What the demo ran and what it skipped, with why (the missing extra, or the step it needed)."""

    ran: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)

    def summary(self) -> str:
        """The closing line: every step ran, or the ones skipped and why."""
        if not self.skipped:
            return f"demo: all {len(self.ran)} steps ran"
        items = "; ".join(f"{name} ({why})" for name, why in self.skipped.items())
        return f"demo: {len(self.ran)} steps ran, {len(self.skipped)} skipped: {items}"


def extra_missing(exc: MissingDependencyError) -> str:
    """Why a step is skipped, in a few words naming the extra and how to install it.

    Parameters
    ----------
    exc : MissingDependencyError
        What the step raised.

    Returns
    -------
    str
        ``"the 'optimize' extra is not installed: pip install 'ftrac_design[optimize]'"``.
    """
    return f"the {exc.extra!r} extra is not installed ({exc.module}): pip install 'ftrac_design[{exc.extra}]'"


def run_steps(steps: list[Step], out: TextIO | None = None) -> Outcome:
    """Run ``steps`` in order, printing each one's text (a blank line between them).

    A step that raises :class:`~ftrac_design.errors.MissingDependencyError` is skipped with one
    line naming the extra; one whose ``needs`` were skipped is skipped without running. Other
    errors propagate.

    Parameters
    ----------
    steps : list of Step
        The steps, in order.
    out : text stream or None
        Where to print (default: ``sys.stdout`` at call time).

    Returns
    -------
    Outcome
        The steps that ran and those skipped.
    """
    out = out if out is not None else sys.stdout
    done = Outcome()
    for k, step in enumerate(steps):
        if k:
            print(file=out)
        blocked = [n for n in step.needs if n in done.skipped]
        if blocked:
            done.skipped[step.name] = f"needs {blocked[0]}, which was skipped"
            print(f"skipped {step.name}: it {done.skipped[step.name]}", file=out)
            continue
        try:
            text = step.run()
        except MissingDependencyError as exc:
            done.skipped[step.name] = f"the {exc.extra!r} extra"
            print(f"skipped {step.name}: {extra_missing(exc)}", file=out)
            continue
        done.ran.append(step.name)
        print(text, file=out)
    return done


def demo_steps(out_dir: Path) -> list[Step]:
    """The demo's steps, on the paper's fiducial built into ``out_dir``.

    The build (its ``features.json`` is written even when the ``cad`` extra is missing), the
    score, a synthetic image solved, the presets' image clearances, a radiograph of the built
    fiducial tracked from the image with no initial guess (overlay written), the pose refined
    on its pixels, a C-arm's Enhanced XA run and an intensifier's distorted frame tracked with
    ``ftrac-design track`` (``carm/``), a small fiducial's near-mirror tie settled by the view
    known beforehand (``view/``), 3-D reconstruction from two tracked views, a tiny design
    search, and the one-page report.

    Parameters
    ----------
    out_dir : pathlib.Path
        The build's directory (``outputs/ftrac_2005``); every step writes beneath it.

    Returns
    -------
    list of Step
        In the order they run.
    """
    from . import (
        build,
        carm,
        intensity,
        optimize,
        radiograph,
        reconstruct,
        report,
        score,
        segmentability,
        solve,
        track,
        view,
    )
    from .shell import relative

    features, image_dir = out_dir / "features.json", out_dir / "radiograph"
    return [
        Step("the build", lambda: build.demo_step(out_dir)),
        Step("the score", lambda: score.demo_step(relative(build.DEFAULT_DESIGN), out_dir / "analysis")),
        Step("the synthetic image", lambda: solve.demo_step(features, out_dir / "synthetic")),
        Step("the image clearances", lambda: segmentability.demo_step(out_dir / "segmentability")),
        Step("the radiograph", lambda: radiograph.demo_step(image_dir)),
        Step("the radiograph tracked", lambda: track.demo_step(features, image_dir), ("the radiograph",)),
        Step("the intensity refinement", lambda: intensity.demo_step(out_dir / "intensity")),
        Step("the C-arm run", lambda: carm.demo_step(out_dir / "carm", features)),
        Step("the view known beforehand", lambda: view.demo_step(out_dir / "view")),
        Step("the reconstruction", lambda: reconstruct.demo_step(out_dir / "reconstruct")),
        Step("the design search", lambda: optimize.demo_step(out_dir / "optimize_demo")),
        Step("the report", lambda: report.demo_step(out_dir), ("the build",)),
    ]


def main(argv: list[str] | None = None, steps: list[Step] | None = None) -> int:
    """Run the demo (``make demo``, ``python -m ftrac_design.demo``); returns the exit code.

    Parameters
    ----------
    argv : list of str or None
        Unused: the demo takes no arguments.
    steps : list of Step or None
        The steps to run (default :func:`demo_steps` into ``outputs/<design name>/``).

    Returns
    -------
    int
        0 when every step ran or was skipped for a missing extra, 2 on bad input, 1 when a step
        failed its goal.
    """
    try:
        if steps is None:
            from ..design import load_design
            from .build import DEFAULT_DESIGN

            steps = demo_steps(Path("outputs") / load_design(DEFAULT_DESIGN).name)
        done = run_steps(steps)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except GoalError as exc:
        print(f"failed: {exc}", file=sys.stderr)
        return 1
    if done.skipped:
        print()
        print(done.summary())
    return 0
