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
#: a number that is not negative
NON_NEGATIVE = click.FloatRange(min=0.0)
#: a whole number that is not negative (a count that may be 0: none)
COUNT = click.IntRange(min=0)
#: a whole number, at least 1
AT_LEAST_ONE = click.IntRange(min=1)
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


class SharedOption:
    """One option as every command that takes it declares it: its flags and parameter name, its
    type and default, and a help text a command may replace with its own words.

    Parameters
    ----------
    *decls : str
        The flags and, last, the parameter's name (``"--features", "features_path"``).
    **attrs
        :func:`click.option`'s attributes (``type``, ``default``, ``help``, …).
    """

    def __init__(self, *decls: str, **attrs):
        self.decls = decls
        self.attrs = attrs

    def __call__(self, help: str | None = None, **override) -> Decorator:
        """The option as a click decorator.

        Parameters
        ----------
        help : str or None
            This command's help (None: the shared one).
        **override
            Attributes this command sets otherwise (``default``, ``required``, ``type``).

        Returns
        -------
        callable
            The click option.
        """
        attrs = {**self.attrs, **override}
        if help is not None:
            attrs["help"] = help
        return click.option(*self.decls, **attrs)


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


#: ``--features FILE`` (required) → ``features_path``
features_option = SharedOption(
    "--features", "features_path", required=True, type=FILE, help="features.json written by `ftrac-design build`."
)
#: ``--camera FILE`` → ``camera_path`` (None when not given)
camera_option = SharedOption("--camera", "camera_path", type=FILE, default=None, help="SPEC §3 camera object (JSON).")
#: ``-o/--output`` → ``output``: a file or a directory (``type=OUT_FILE`` / ``OUT_DIR`` for one of them)
output_option = SharedOption("-o", "--output", "output", type=click.Path(path_type=Path), default=None)
#: an output that is a file
OUT_FILE = click.Path(path_type=Path, dir_okay=False)
#: a directory, read or written (``--analysis DIR``, ``--scene DIR``)
DIR = click.Path(path_type=Path, file_okay=False)
#: an output that is a directory
OUT_DIR = DIR


def flag_option(*decls: str, help: str) -> Decorator:
    """A switch that is off unless given (``is_flag``, default False).

    Parameters
    ----------
    *decls : str
        The flag and, optionally, the parameter's name.
    help : str
        What the switch does.

    Returns
    -------
    callable
        The click option.
    """
    return click.option(*decls, is_flag=True, default=False, help=help)


def optional_option(*decls: str, type, help: str, **attrs) -> Decorator:
    """An option that is None unless given (``--pose FILE``, ``--max-condition X``).

    Parameters
    ----------
    *decls : str
        The flags and, optionally, the parameter's name.
    type : click.ParamType or type
        Its values' type.
    help : str
        What it sets.
    **attrs
        Further attributes of :func:`click.option` (``metavar``, ``required``).

    Returns
    -------
    callable
        The click option.
    """
    return click.option(*decls, type=type, default=None, help=help, **attrs)


def shown_option(*decls: str, type, default, help: str, **attrs) -> Decorator:
    """An option whose default ``--help`` shows (``show_default``).

    Parameters
    ----------
    *decls : str
        The flags and, optionally, the parameter's name.
    type : click.ParamType or type
        Its values' type.
    default
        Its value when not given.
    help : str
        What it sets.
    **attrs
        Further attributes of :func:`click.option` (``metavar``).

    Returns
    -------
    callable
        The click option.
    """
    return click.option(*decls, type=type, default=default, show_default=True, help=help, **attrs)


def _choice(flag: str, choices, default: str, help: str | None = None) -> SharedOption:
    return SharedOption(flag, type=click.Choice(list(choices)), default=default, show_default=True, help=help)


#: ``--profile cnc|fdm`` → ``profile`` (default cnc)
profile_option = _choice("--profile", PROFILES, "cnc", "manufacturing profile: sets groove widths and pocket diameters")
#: ``--profile cnc|fdm``, repeatable → ``profiles`` (empty when not given)
profiles_option = SharedOption("--profile", "profiles", type=click.Choice(PROFILES), multiple=True)
#: ``--post linuxcnc|fanuc`` → ``post`` (:data:`ftrac_design.machining.post.POSTS`)
post_option = _choice("--post", POSTS, DEFAULT_POST, "the control the program is written for")
#: ``--polarity auto|dense-dark|dense-bright`` → ``polarity`` (default auto)
polarity_option = _choice(
    "--polarity", POLARITIES, "auto", "dense-dark: raw detector counts; dense-bright: log/display image."
)
#: ``--detector auto|learned|classical`` → ``detector`` (default auto): how the features are found
detector_option = _choice(
    "--detector",
    ("auto", "learned", "classical"),
    "auto",
    "what finds the balls and the fiducial's region: learned (the shipped network, ONNX Runtime: the "
    "detect extra), classical (blob detector and half-size search), auto (learned where ONNX Runtime "
    "is installed, then classical where the learned finds no pose; else classical). Either way the "
    "labelling, the pose and its tests are the same.",
)
#: ``--distortion FILE|none`` → ``distortion_path``: an ftrac-distortion model, or none (a flat panel)
distortion_option = SharedOption("--distortion", "distortion_path", type=FILE, default=None)
#: ``--refine none|intensity`` → ``refine`` (default none)
refine_option = _choice("--refine", ("none", "intensity"), "none")
#: ``--independent`` (a flag): every frame tracked alone, no prior
independent_option = SharedOption("--independent", is_flag=True)
#: ``--expect-view POSE.json`` → ``view_path``: the view as known beforehand (a SPEC §4 pose)
view_option = SharedOption(
    "--expect-view",
    "view_path",
    type=FILE,
    default=None,
    help="SPEC §4 pose.json of the view as known beforehand (an earlier image of the same set-up, or "
    "one written from the C-arm's angles and the fiducial's mount): only answers whose rotation is "
    "within --view-within-deg of its rotation are looked for and given out; its translation is not "
    "used. It decides between a near-mirror pair of answers the image alone cannot tell apart (a "
    "small fiducial far from the source); a wrong one gives a wrong answer.",
)
#: ``--view-within-deg DEG`` → ``view_within_deg`` (default 45)
view_within_option = SharedOption(
    "--view-within-deg",
    type=click.FloatRange(0.0, 180.0, min_open=True),
    default=45.0,
    show_default=True,
    help="how far (degrees) the view's rotation may be from --expect-view's",
)
#: ``--poses N`` (at least 100) → ``poses`` (None: the design's or the command's default)
poses_option = SharedOption(
    "--poses",
    type=click.IntRange(min=100),
    default=None,
    help="random workspace poses scored [default: the design's, else 20000]",
)
#: ``--workers N`` → ``workers`` (None: one per core; 0: this process)
workers_option = SharedOption(
    "--workers",
    type=COUNT,
    default=None,
    help="processes rendering and tracking the score's images [default: one per core; 0 = this process]",
)
#: ``--min-clearance-px PX`` → ``min_clearance_px``: 5th-percentile image clearance between features
min_clearance_option = SharedOption("--min-clearance-px", type=float, default=None)
#: ``--score-images N`` → ``score_images``: the image-true score's images per condition
score_images_option = SharedOption(
    "--score-images",
    type=COUNT,
    default=100,
    show_default=True,
    help="the image-true score: workspace poses rendered and tracked per condition (clean, over a "
    "patient), the same images for every design; 0 = the paper's feature-level model only",
)
#: ``--host ADDRESS`` (default 127.0.0.1)
host_option = SharedOption("--host", default="127.0.0.1", show_default=True)
#: ``--port N`` (default 18944, OpenIGTLink's; ``type=click.IntRange(0, 65535)`` lets a server take any free one)
port_option = SharedOption("--port", type=click.IntRange(1, 65535), default=18944, show_default=True)


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
        optional_option("--seed", type=int, help="random seed of the workspace poses [default: 0]"),
        optional_option(
            "--cone-deg",
            type=click.FloatRange(min=0.0, max=180.0, min_open=True),
            help="workspace: beams within this angle of the nominal beam; 180 = the whole sphere [default: 25]",
        ),
        optional_option(
            "--roll-range-deg",
            type=(float, float),
            help="workspace: roll about the beam drawn from this range [default: 0 360]",
            metavar="FROM TO",
        ),
        optional_option("--depth-mm", type=POSITIVE, help="workspace: source to fiducial origin [default: 667]"),
        optional_option("--depth-range-mm", type=NON_NEGATIVE, help="workspace: ± this about the depth [default: 25]"),
        optional_option(
            "--lateral-mm", type=NON_NEGATIVE, help="workspace: origin within this of the principal ray [default: 25]"
        ),
        optional_option(
            "--segmentation-error-mm",
            type=POSITIVE,
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
        shown_option("--score-seed", type=int, default=0, help="seed of the image-true score's sample"),
    ]
    if atlas:
        opts.append(
            shown_option(
                "--image-atlas-step-deg",
                type=click.FloatRange(min=0.0, max=45.0),
                default=20.0,
                help="the image-true blind-spot atlas: grid step over the sphere of view directions, each "
                "direction imaged (clean) and tracked at 2 rolls; 0 = none",
            )
        )
    return stack(*opts, workers_option())


def imaging_options(prefix: str = "") -> Decorator:
    """The imaging model's physics (:class:`ftrac_design.xray.ImagingModel`): ``--energy-kev``,
    ``--dose`` (→ its photons per pixel), ``--focal-spot-mm`` and ``--detector-blur-px``.

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
        shown_option(
            "--energy-kev",
            type=click.FloatRange(40.0, 100.0),
            default=60.0,
            help=prefix + "effective beam energy for the attenuation coefficients.",
        ),
        shown_option(
            "--dose",
            type=POSITIVE,
            default=1.0e4,
            help=prefix + "unattenuated quanta per detector pixel (sets the quantum noise).",
        ),
        shown_option("--focal-spot-mm", type=NON_NEGATIVE, default=0.6, help=prefix + "focal spot size (FWHM)."),
        shown_option(
            "--detector-blur-px",
            "detector_blur_px",
            type=NON_NEGATIVE,
            default=0.7,
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
        shown_option("--space", type=click.Choice(["ras", "lps"]), default="ras", help=space_help),
    )
