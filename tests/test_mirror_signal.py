"""A view against its mirror image: how far perspective sets them apart
(:func:`ftrac_design.segment.region.mirror_signal_px`), and the one ball fewer a confident
labelling may use where that is beyond the matching tolerances
(:func:`ftrac_design.segment.region.balls_needed`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, Pose
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import TrackOptions
from ftrac_design.segment.identify import project
from ftrac_design.segment.region import balls_needed, mirror_signal_px, outline_points


@pytest.fixture(scope="module")
def mini():
    return compute_features(load_design("ftrac_mini"))


def _poses(features, n, seed):
    return Workspace().sample(n, features.nominal_beam_direction, np.random.default_rng(seed))


def test_an_affine_camera_cannot_tell_a_view_from_its_mirror(f2005):
    """The signal is perspective alone: with the source pushed back and the focal length
    with it (the same image scale, an ever more affine projection) it falls as 1 / distance —
    the projective term of a point is its image offset times its relative depth."""
    R, t = _poses(f2005, 1, 4)
    base = Camera()
    near = mirror_signal_px(f2005, base, R[0], t[0])
    u0, _ = project(base, R[0], t[0], outline_points(f2005))
    for k in (4.0, 16.0):
        far = replace(base, focal_length_mm=base.focal_length_mm * k)
        u1, _ = project(far, R[0], k * t[0], outline_points(f2005))
        assert np.ptp(u1, axis=0) == pytest.approx(np.ptp(u0, axis=0), rel=0.1)
        assert mirror_signal_px(f2005, far, R[0], k * t[0]) == pytest.approx(near / k, rel=0.15)


def test_a_view_and_its_mirror_image_differ_by_the_reflected_points_own_residual(f2005):
    """By construction: the points reflected through the plane square to the line of sight,
    projected and mapped onto the view by the least-squares affine map, leave the returned
    largest distance (computed here directly)."""
    cam = Camera()
    R, t = _poses(f2005, 1, 9)
    X = outline_points(f2005) @ R[0].T + t[0]
    c = X.mean(0)
    d = c / np.linalg.norm(c)
    M = X - 2.0 * np.outer((X - c) @ d, d)
    # a reflection: distances kept, the centroid fixed
    np.testing.assert_allclose(
        np.linalg.norm(M[:, None] - M[None], axis=-1), np.linalg.norm(X[:, None] - X[None], axis=-1), atol=1e-9
    )
    u = cam.fx * X[:, :2] / X[:, 2:]
    m = cam.fx * M[:, :2] / M[:, 2:]
    A = np.c_[m, np.ones(len(m))]
    coef = np.linalg.lstsq(A, u, rcond=None)[0]
    assert mirror_signal_px(f2005, cam, R[0], t[0]) == pytest.approx(np.linalg.norm(A @ coef - u, axis=1).max())
    # a pose behind the source has no view
    assert mirror_signal_px(f2005, cam, R[0], -t[0]) == 0.0


def test_the_small_fiducial_never_reaches_the_threshold_in_the_workspace(f2005, mini):
    """The premise of ``mirror_signal_px``'s default: over SPEC §1's workspace ftrac_mini's
    views stay within a fraction of the matching tolerance of their mirror (so its labellings
    keep needing five balls), while ftrac_2005's are all set apart."""
    opts = TrackOptions()
    cam = Camera()
    R, t = _poses(mini, 300, 11)
    small = [mirror_signal_px(mini, cam, R[k], t[k]) for k in range(len(R))]
    assert max(small) < 0.25 * opts.mirror_signal_px
    R, t = _poses(f2005, 300, 11)
    large = np.array([mirror_signal_px(f2005, cam, R[k], t[k]) for k in range(len(R))])
    assert large.min() >= opts.mirror_signal_px


def test_one_ball_fewer_only_with_wires_and_a_view_apart_from_its_mirror(f2005, mini):
    opts = TrackOptions()
    accept = opts.acceptance
    cam = Camera()
    R, t = _poses(f2005, 1, 12)
    signal = mirror_signal_px(f2005, cam, R[0], t[0])
    assert signal >= accept.mirror_signal_px

    def pose(k, scale=1.0):
        return Pose(R[k], scale * t[k], True, 1.0, None, {}, 0, None)

    apart = 0
    assert balls_needed(f2005, cam, pose(apart), True, accept) == opts.min_beads - 1
    assert balls_needed(f2005, cam, pose(apart), False, accept) == opts.min_beads
    # five times as far (and five times the focal length: the same image), the view is within
    # the threshold of its mirror
    far = replace(cam, focal_length_mm=5 * cam.focal_length_mm)
    assert mirror_signal_px(f2005, far, R[0], 5 * t[0]) < accept.mirror_signal_px
    assert balls_needed(f2005, far, pose(apart, 5.0), True, accept) == opts.min_beads
    off = TrackOptions(mirror_signal_px=0.0).acceptance
    assert balls_needed(f2005, cam, pose(apart), True, off) == opts.min_beads
    Rm, tm = _poses(mini, 60, 12)
    assert all(
        balls_needed(mini, cam, Pose(Rm[k], tm[k], True, 1.0, None, {}, 0, None), True, accept) == opts.min_beads
        for k in range(len(Rm))
    )
    # never below four, and a design of fewer balls needs at most all of them
    four = TrackOptions(min_beads=4).acceptance
    assert balls_needed(f2005, cam, pose(apart), True, four) == 4
