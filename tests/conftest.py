"""Shared fixtures: the preset designs and their features."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.design.presets import PRESETS_DIR
from ftrac_design.features import compute_features
from ftrac_design.pose.simulate import Workspace

ROOT = Path(__file__).resolve().parents[1]
MODELS = PRESETS_DIR
PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")


@pytest.fixture(scope="session")
def models_dir() -> Path:
    return MODELS


@pytest.fixture(scope="session", params=PRESETS)
def preset(request) -> str:
    return request.param


@pytest.fixture(scope="session")
def design_2005():
    return load_design(MODELS / "ftrac_2005.toml")


@pytest.fixture(scope="session")
def features_2005(design_2005):
    return compute_features(design_2005)


@pytest.fixture(scope="session")
def f2005(features_2005):
    """ftrac_2005's features, its acetal body included, as the radiograph simulator takes them."""
    return features_2005


@pytest.fixture(scope="session")
def pose_2005(features_2005):
    """One workspace pose (R, t) of ftrac_2005 (sample seed 4), camera frame X, mm."""
    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(4))
    return R[0], t[0]


@pytest.fixture(scope="session")
def displaced_by_mode():
    """``f(obs, k)``: the observation with every point and contour point moved by distortion
    mode ``k`` of :func:`ftrac_design.segment.noise.distortion_modes` (1 mm at 100 mm)."""
    from ftrac_design.pose.observation import CurveObservation, Observation
    from ftrac_design.segment.noise import distortion_modes

    def displaced(obs: Observation, k: int) -> Observation:
        def mv(uv):
            return uv + distortion_modes(obs.camera, uv, 100.0)[k]

        return Observation(
            obs.camera,
            {i: mv(np.asarray(v, float)[None])[0] for i, v in obs.points.items()},
            {i: CurveObservation(points=mv(c.points)) for i, c in obs.lines.items()},
            {i: CurveObservation(points=mv(c.points)) for i, c in obs.ellipses.items()},
            obs.origin,
        )

    return displaced


@pytest.fixture
def another_fiducial():
    """``track(k, seed, preset)``: the no-fiducial benchmark's "another fiducial" image ``k`` of
    ``seed`` (``benchmarks/no_fiducial.py``) tracked as ``preset`` with default options, its
    principal point at the image's centre, as a user with a PNG of it would; returns the
    preset the image shows and the :class:`~ftrac_design.segment.TrackResult`."""
    import sys

    from ftrac_design.pose import Camera
    from ftrac_design.segment import track_image

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from no_fiducial import fiducial

    def track(k: int, seed: int, preset: str):
        img, shown = fiducial(k, seed)
        camera = Camera(principal_point_px=(img.shape[1] / 2, img.shape[0] / 2))
        return shown, track_image(img, compute_features(load_design(preset)), camera)

    return track


@pytest.fixture
def realism_tracked():
    """``track(preset, condition, k, seed, n, opts=None)``: the realism benchmark's image ``k``
    of ``condition`` (``benchmarks/track_realism.py``, ``n`` per condition, ``seed``) tracked as
    ``preset`` (default options unless ``opts``); returns the
    :class:`~ftrac_design.segment.TrackResult`, the pose's rotation and translation errors
    against the truth (degrees, mm) and the χ²₆ of its error under its own covariance (inf
    when refused)."""
    import math
    import sys

    from ftrac_design.pose.simulate import pose_errors
    from ftrac_design.segment import TrackOptions, track_image

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from track_realism import make_image

    def track(preset: str, condition: str, k: int, seed: int, n: int, opts: TrackOptions | None = None):
        img, R, t, camera, _ = make_image(preset, condition, k, seed, n)
        res = track_image(img, compute_features(load_design(preset)), camera, opts or TrackOptions())
        if not res.pose.converged:
            return res, math.inf, math.inf, math.inf
        dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R, t)
        e = np.concatenate([dr, dt])
        return (
            res,
            math.degrees(float(np.linalg.norm(dr))),
            float(np.linalg.norm(dt)),
            float(e @ np.linalg.solve(res.pose.covariance, e)),
        )

    return track
