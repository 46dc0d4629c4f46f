"""The command line's shared options, each defined once: its flag, its parameter's name (the
field it fills, so ``--depth-mm`` arrives as ``depth_mm``), its type, its default and a help
text that a command may put in its own words.

Each factory returns a click decorator: ``@features_option()``, ``@profile_option("…")``.
The groups used together (the workspace, the image-true score, the OpenIGTLink link) are one
decorator each.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import click

from ..machining.post import DEFAULT_POST, POSTS
from ..manufacture.profiles import PROFILES

Decorator = Callable[[Callable], Callable]

#: a file that must not be a directory (``--features``, ``--camera``, …)
FILE = click.Path(dir_okay=False, path_type=Path)
#: a positive number
POSITIVE = click.FloatRange(min=0.0, min_open=True)
#: how dense matter looks in an image
POLARITIES = ("auto", "dense-dark", "dense-bright")


def stack(*decorators: Decorator) -> Decorator:
    """Several options as one decorator, listed as ``--help`` shows them (top to bottom).

    Parameters
    ----------
    *decorators : callable
        click decorators.

    Returns
    -------
    callable
        A decorator applying all of them.
    """

    def decorate(fn: Callable) -> Callable:
        for d in reversed(decorators):
            fn = d(fn)
        return fn

    return decorate


def design_argument(dir_okay: bool = True) -> Decorator:
    """``DESIGN``: a design file or a preset's name (:func:`ftrac_design.design.presets.resolve_design`).

    Parameters
    ----------
    dir_okay : bool
        Whether a directory of that name is passed through (to be reported by the reader).

    Returns
    -------
    callable
        The click argument ``design`` (a :class:`pathlib.Path`).
    """
    return click.argument("design", type=click.Path(path_type=Path, dir_okay=dir_okay))


def features_option(help: str = "features.json written by `ftrac-design build`.") -> Decorator:
    """``--features FILE`` (required) → ``features_path``.

    Parameters
    ----------
    help : str
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--features", "features_path", required=True, type=FILE, help=help)


def camera_option(help: str = "SPEC §3 camera object (JSON).") -> Decorator:
    """``--camera FILE`` → ``camera_path`` (None when not given).

    Parameters
    ----------
    help : str
        The option's help (what the camera overrides in this command).

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--camera", "camera_path", type=FILE, default=None, help=help)


def output_option(
    help: str, kind: str = "path", default: Path | None = None, required: bool = False, show_default: bool = False
) -> Decorator:
    """``-o/--output`` → ``output``.

    Parameters
    ----------
    help : str
        What is written there, and the default.
    kind : {"path", "file", "dir"}
        Whether the output is a file, a directory or either.
    default : pathlib.Path or None
        The default output.
    required : bool
        Whether it must be given.
    show_default : bool
        Whether ``--help`` shows ``default``.

    Returns
    -------
    callable
        The click option.
    """
    ok = {"path": {}, "file": {"dir_okay": False}, "dir": {"file_okay": False}}[kind]
    return click.option(
        "-o",
        "--output",
        "output",
        type=click.Path(path_type=Path, **ok),
        default=default,
        required=required,
        show_default=show_default,
        help=help,
    )


def profile_option(
    help: str = "manufacturing profile: sets groove widths and pocket diameters", multiple: bool = False
) -> Decorator:
    """``--profile cnc|fdm`` → ``profile`` (default cnc), or with ``multiple`` ``profiles``
    (repeatable, empty when not given).

    Parameters
    ----------
    help : str
        What the profile decides in this command.
    multiple : bool
        Whether the option repeats.

    Returns
    -------
    callable
        The click option.
    """
    if multiple:
        return click.option("--profile", "profiles", type=click.Choice(PROFILES), multiple=True, help=help)
    return click.option("--profile", type=click.Choice(PROFILES), default="cnc", show_default=True, help=help)


def post_option(help: str = "the control the program is written for") -> Decorator:
    """``--post linuxcnc|fanuc`` → ``post`` (:data:`ftrac_design.machining.post.POSTS`).

    Parameters
    ----------
    help : str
        Which program the post writes, in this command.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--post", type=click.Choice(list(POSTS)), default=DEFAULT_POST, show_default=True, help=help)


def polarity_option(help: str = "dense-dark: raw detector counts; dense-bright: log/display image.") -> Decorator:
    """``--polarity auto|dense-dark|dense-bright`` → ``polarity`` (default auto).

    Parameters
    ----------
    help : str
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--polarity", type=click.Choice(POLARITIES), default="auto", show_default=True, help=help)


def distortion_option(help: str) -> Decorator:
    """``--distortion FILE|none`` → ``distortion_path``: an ``ftrac-distortion`` model, or
    ``none`` for a detector that does not distort.

    Parameters
    ----------
    help : str
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--distortion", "distortion_path", type=FILE, default=None, help=help)


def refine_option(help: str) -> Decorator:
    """``--refine none|intensity`` → ``refine`` (default none).

    Parameters
    ----------
    help : str
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option(
        "--refine", type=click.Choice(["none", "intensity"]), default="none", show_default=True, help=help
    )


def independent_option(help: str) -> Decorator:
    """``--independent`` (a flag) → ``independent``: every frame tracked alone, no prior.

    Parameters
    ----------
    help : str
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--independent", is_flag=True, help=help)


def poses_option(help: str = "random workspace poses scored [default: the design's, else 20000]") -> Decorator:
    """``--poses N`` (at least 100) → ``poses`` (None: the design's or the command's default).

    Parameters
    ----------
    help : str
        Which poses, in this command.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--poses", type=click.IntRange(min=100), default=None, help=help)


def workers_option(
    help: str = "processes rendering and tracking the score's images [default: one per core; 0 = this process]",
) -> Decorator:
    """``--workers N`` → ``workers`` (None: one per core; 0: this process).

    Parameters
    ----------
    help : str
        What the workers do, in this command.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--workers", type=click.IntRange(min=0), default=None, help=help)


def min_clearance_option(help: str) -> Decorator:
    """``--min-clearance-px PX`` → ``min_clearance_px``: the 5th-percentile smallest image
    clearance between features, px beyond their widths.

    Parameters
    ----------
    help : str
        How the command uses it (a pass threshold, a search constraint).

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--min-clearance-px", type=float, default=None, help=help)


def score_images_option(
    default: int = 100,
    help: str = "the image-true score: workspace poses rendered and tracked per condition (clean, over a "
    "patient), the same images for every design; 0 = the paper's feature-level model only",
) -> Decorator:
    """``--score-images N`` → ``score_images``: the image-true score's images per condition.

    Parameters
    ----------
    default : int
        Images per condition when not given (0: the score is not computed).
    help : str
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--score-images", type=click.IntRange(min=0), default=default, show_default=True, help=help)


def workspace_options() -> Decorator:
    """The workspace, noise and sampling of the paper's model (``analyze``, ``compare``), each
    named as its field of :class:`~ftrac_design.analysis.score.AnalysisSettings` and
    :class:`~ftrac_design.pose.simulate.Workspace` (``--depth-mm`` → ``depth_mm``); None where
    not given, so the design's ``[analysis]`` table or the defaults decide
    (:func:`ftrac_design.analysis.subject.settings_for`).

    Returns
    -------
    callable
        One decorator for ``--poses``, ``--seed``, ``--cone-deg``, ``--roll-range-deg``,
        ``--depth-mm``, ``--depth-range-mm``, ``--lateral-mm`` and ``--segmentation-error-mm``.
    """
    return stack(
        poses_option(),
        click.option("--seed", type=int, default=None, help="random seed of the workspace poses [default: 0]"),
        click.option(
            "--cone-deg",
            type=click.FloatRange(min=0.0, max=180.0, min_open=True),
            default=None,
            help="workspace: beams within this angle of the nominal beam; 180 = the whole sphere [default: 25]",
        ),
        click.option(
            "--roll-range-deg",
            type=(float, float),
            default=None,
            metavar="FROM TO",
            help="workspace: roll about the beam drawn from this range [default: 0 360]",
        ),
        click.option(
            "--depth-mm", type=POSITIVE, default=None, help="workspace: source to fiducial origin [default: 667]"
        ),
        click.option(
            "--depth-range-mm",
            type=click.FloatRange(min=0.0),
            default=None,
            help="workspace: ± this about the depth [default: 25]",
        ),
        click.option(
            "--lateral-mm",
            type=click.FloatRange(min=0.0),
            default=None,
            help="workspace: origin within this of the principal ray [default: 25]",
        ),
        click.option(
            "--segmentation-error-mm",
            type=POSITIVE,
            default=None,
            help="the paper's uniform segmentation error magnitude, mm at the detector [default: 0.25]",
        ),
    )


def image_score_options(atlas: bool = False) -> Decorator:
    """The image-true score's sample (``--score-images``, ``--score-seed``), with ``atlas`` its
    blind-spot atlas (``--image-atlas-step-deg``), and the processes that render and track
    (``--workers``): ``analyze``, ``compare`` and ``report``
    (:meth:`ftrac_design.workflows.analyze.ImageScoring.from_options`).

    Parameters
    ----------
    atlas : bool
        Whether the command draws the image-true atlas.

    Returns
    -------
    callable
        One decorator for those options.
    """
    opts = [
        score_images_option(),
        click.option(
            "--score-seed", type=int, default=0, show_default=True, help="seed of the image-true score's sample"
        ),
    ]
    if atlas:
        opts.append(
            click.option(
                "--image-atlas-step-deg",
                type=click.FloatRange(min=0.0, max=45.0),
                default=20.0,
                show_default=True,
                help="the image-true blind-spot atlas: grid step over the sphere of view directions, each "
                "direction imaged (clean) and tracked at 2 rolls; 0 = none",
            )
        )
    return stack(*opts, workers_option())


def imaging_options(prefix: str = "") -> Decorator:
    """The imaging model's physics (:class:`ftrac_design.xray.ImagingModel`): ``--energy-kev``,
    ``--dose`` (→ its photons per pixel), ``--focal-spot-mm`` and ``--detector-blur-px``
    (also ``--blur-px``).

    Parameters
    ----------
    prefix : str
        Put before each help (``"imaging: "``).

    Returns
    -------
    callable
        One decorator for the four.
    """
    return stack(
        click.option(
            "--energy-kev",
            type=click.FloatRange(40.0, 100.0),
            default=60.0,
            show_default=True,
            help=prefix + "effective beam energy for the attenuation coefficients.",
        ),
        click.option(
            "--dose",
            type=POSITIVE,
            default=1.0e4,
            show_default=True,
            help=prefix + "unattenuated quanta per detector pixel (sets the quantum noise).",
        ),
        click.option(
            "--focal-spot-mm",
            type=click.FloatRange(min=0.0),
            default=0.6,
            show_default=True,
            help=prefix + "focal spot size (FWHM).",
        ),
        click.option(
            "--detector-blur-px",
            "--blur-px",
            "detector_blur_px",
            type=click.FloatRange(min=0.0),
            default=0.7,
            show_default=True,
            help=prefix + "Gaussian σ of the detector line-spread, pixels.",
        ),
    )


def link_options(
    space_help: str, name_help: str = "TRANSFORM device name, PLUS <From>To<To>, at most 20 characters."
) -> Decorator:
    """The transform's name and coordinates as OpenIGTLink, ITK and PLUS files carry them:
    ``--name`` (default ``FiducialToCArm``) and ``--space ras|lps`` (default ras).

    Parameters
    ----------
    space_help : str
        What the coordinates apply to, in this command.
    name_help : str
        Where the name goes, in this command.

    Returns
    -------
    callable
        One decorator for both.
    """
    return stack(
        click.option("--name", default="FiducialToCArm", show_default=True, help=name_help),
        click.option("--space", type=click.Choice(["ras", "lps"]), default="ras", show_default=True, help=space_help),
    )


def host_option(help: str) -> Decorator:
    """``--host ADDRESS`` (default 127.0.0.1).

    Parameters
    ----------
    help : str
        Which address: the one listened on, or the server's.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--host", default="127.0.0.1", show_default=True, help=help)


def port_option(lowest: int = 1, help: str | None = None) -> Decorator:
    """``--port N`` (default 18944, OpenIGTLink's).

    Parameters
    ----------
    lowest : int
        The smallest port accepted (0: any free one, for a server).
    help : str or None
        The option's help.

    Returns
    -------
    callable
        The click option.
    """
    return click.option("--port", type=click.IntRange(lowest, 65535), default=18944, show_default=True, help=help)
