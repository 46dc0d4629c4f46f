"""Training scenes for the learned detector: a random fiducial at a random pose in a random C-arm
image, with the exact truth of every ball and wire.

Each scene is drawn from its own seed: a design (a shipped preset, or one of them moved
anywhere in its default design space and given other ball and wire diameters — so the network
learns balls and wires, not one fiducial), a pose in a wider workspace than the tracker's
(cone 35°, 420–900 mm from the source), one of the simulator's conditions
(:data:`ftrac_design.xray.scenario.CONDITIONS`, or a clean image), and where the fiducial lands
in the window. The window is what a detector sees of a C-arm image around the fiducial: the
image chain's window, gamma and noise are computed on it, as on the whole image.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..design import Body, load_design
from ..design.loader import parse_design
from ..design.presets import preset_names
from ..errors import InputError
from ..features import compute_features
from ..features.model import Features
from ..pose import Camera
from ..pose.simulate import Workspace
from ..segment.detection import scales
from ..segment.identify import curve_samples, project
from ..segment.options import TrackOptions
from ..xray import render
from ..xray.model import ImagingModel
from ..xray.scenario import CONDITIONS, realistic_image

#: the conditions a scene is drawn from: the simulator's, and clean images
SCENE_CONDITIONS: tuple[str, ...] = ("clean",) + CONDITIONS
#: the training workspace: wider than SPEC §1's, so that the network sees every size a ball can have
TRAIN_WORKSPACE = Workspace(cone_deg=35.0, depth_mm=660.0, depth_range_mm=240.0, lateral_mm=20.0)
#: the camera of every scene (SPEC §1's), its principal point moved to place the window
CAMERA = Camera()


@dataclass(frozen=True)
class Scene:
    """One training image and its truth.

    Attributes
    ----------
    image : (H, W) ndarray
        The stored pixels (uint16 counts, float32 log, uint8 display).
    valid : (H, W) bool ndarray
        Where the image can be read (the exposed field).
    beads_uv : (n, 2) ndarray
        Projected ball centres (px), those in the window only.
    curves : list of (m, 2) ndarray
        Every wire's projected centre-line, sampled every 0.5 px.
    bead_radius_px : float
        The design's ball radius at the tracker's assumed magnification (px): sets the working scale.
    design : str
        What was drawn (preset name, ``+space`` when moved in its space).
    condition : str
        The image condition.
    """

    image: np.ndarray
    valid: np.ndarray
    beads_uv: np.ndarray
    curves: list[np.ndarray]
    bead_radius_px: float
    design: str
    condition: str


_PRESETS: dict[str, tuple[dict, Features, Body]] = {}


def _preset(name: str) -> tuple[dict, Features, Body]:
    if name not in _PRESETS:
        import tomllib

        design = load_design(name)
        with open(design.source, "rb") as f:
            data = tomllib.load(f)
        _PRESETS[name] = (data, compute_features(design), design.body)
    return _PRESETS[name]


def random_design(rng: np.random.Generator, presets: tuple[str, ...] | None = None) -> tuple[Features, Body, str]:
    """A preset family (ftrac_2005, ftrac_mini and its variants, nine_bead: equally often), one of
    its presets as shipped (half the draws), or moved anywhere in its default design space with
    its ball diameter × 0.7–1.5 and wire diameter × 0.8–1.6 (the rest). A draw the design's
    rules refuse is drawn again (twenty times at most, then the preset as shipped)."""
    from ..optimize.space import default_space

    names = presets or tuple(preset_names())
    # by family, so that the four variants of the 1 × 1 × 2 cm design do not outweigh the rest
    families: dict[str, list[str]] = {}
    for n in names:
        families.setdefault(n.split("_")[0] + "_" + n.split("_")[1] if "_" in n else n, []).append(n)
    keys = sorted(families)
    group = families[keys[int(rng.integers(len(keys)))]]
    name = group[int(rng.integers(len(group)))]
    data, features, body = _preset(name)
    if rng.random() < 0.5:
        return features, body, name
    try:
        space = default_space(data)
    except InputError:  # nothing to move (a design of balls alone)
        return features, body, name
    bead = float(data.get("bead", {}).get("diameter", 2.0))
    wire = float(data.get("wire", {}).get("diameter", 0.5))
    for _ in range(20):
        cand = space.candidate(rng.random(space.dim))
        cand.setdefault("bead", {})["diameter"] = round(bead * float(rng.uniform(0.7, 1.5)), 2)
        cand.setdefault("wire", {})["diameter"] = round(wire * float(rng.uniform(0.8, 1.6)), 2)
        try:
            design = parse_design(cand, f"{name}+space")
            return compute_features(design), design.body, f"{name}+space"
        except (InputError, ValueError):
            continue
    return features, body, name


def _window_camera(features: Features, R: np.ndarray, t: np.ndarray, side: int, rng) -> Camera:
    """SPEC §1's camera with its principal point moved so that the fiducial's origin lands at a
    random place of a ``side`` × ``side`` window, at least a quarter of the side from its edges."""
    u0 = CAMERA.focal_length_mm * t[0] / t[2] / CAMERA.pixel_size_mm[0]
    v0 = CAMERA.focal_length_mm * t[1] / t[2] / CAMERA.pixel_size_mm[1]
    target = rng.uniform(0.25 * side, 0.75 * side, 2)
    return replace(CAMERA, principal_point_px=(float(target[0] - u0), float(target[1] - v0)))


def make_scene(seed: int, presets: tuple[str, ...] | None = None, side: int | None = None) -> Scene:
    """The training scene of ``seed`` (see the module).

    Parameters
    ----------
    seed : int
        Draws everything; the same seed gives the same scene on any machine.
    presets : tuple of str, optional
        The presets designs are drawn from (default every shipped one).
    side : int, optional
        The window's side (px); default a whole 1024² frame one time in five, else 768 for
        balls of 2.5 px radius or more and 512 for smaller ones.

    Returns
    -------
    Scene
    """
    rng = np.random.default_rng([int(seed), 7331])
    features, body, name = random_design(rng, presets)
    R, t = TRAIN_WORKSPACE.sample(1, features.nominal_beam_direction, rng)
    R, t = R[0], t[0]
    rb = scales(features, CAMERA, TrackOptions().finding).bead_radius_px
    # a fifth of the scenes are whole 1024² frames: the display chain's window is taken over them
    side = side or (1024 if rng.random() < 0.2 else 768 if rb >= 2.5 else 512)
    camera = _window_camera(features, R, t, side, rng)
    condition = SCENE_CONDITIONS[int(rng.integers(len(SCENE_CONDITIONS)))]
    img_seed = int(rng.integers(2**31))
    if condition == "clean":
        imaging = ImagingModel(image_shape=(side, side))
        rad = render(features, R, t, camera, imaging, rng=np.random.default_rng(img_seed))
        image, valid = rad.raw, np.ones((side, side), bool)
    else:
        image, info = realistic_image(features, R, t, camera, condition, img_seed, shape=(side, side))
        valid = np.asarray(info["field_mask"], bool)
    uv = project(camera, R, t, features.point_centers())[0] if features.points else np.zeros((0, 2))
    inside = (uv >= 0).all(1) & (uv[:, 0] <= side - 1) & (uv[:, 1] <= side - 1)
    curves = [pts for _, pts in curve_samples(features, camera, R, t).values()]
    return Scene(image, valid, uv[inside], curves, rb, name, condition)
