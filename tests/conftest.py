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
