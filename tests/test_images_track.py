"""End to end: a simulated radiograph written as an Enhanced XA file stored rotated and
flipped (FieldOfViewRotation 90°, horizontal flip) is read back on the detector grid with
the same camera, and the fiducial's pose found from it is the true one."""

from __future__ import annotations

import numpy as np
import pytest
from fuzz_support import MODELS

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.images import read_frames, write_dicom
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.segment.pipeline import track_image
from ftrac_design.xray import render


@pytest.mark.parametrize("rotation,flip", [(0, False), (90, True)])
def test_a_rotated_enhanced_xa_run_tracks_the_true_pose(tmp_path, rotation, flip):
    features = compute_features(load_design(MODELS / "ftrac_2005.toml"))
    cam = Camera(1000.0, (0.44, 0.44), (500.0, 520.0))
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(4))
    rad = render(features, R[0], t[0], cam, rng=np.random.default_rng(4))
    counts = np.clip(np.rint(rad.raw), 0, 65535).astype(np.uint16)  # detector counts: dense = dark
    p = write_dicom(
        tmp_path / "run.dcm",
        counts,
        cam,
        kind="enhanced-xa",
        relationship="LIN",
        relationship_sign=1,
        fov_rotation_deg=rotation,
        fov_horizontal_flip=flip,
        isocenter_projection_px=(500.0, 520.0),
    )
    (frame,) = list(read_frames(p))
    assert np.array_equal(frame.pixels, counts) and frame.camera == cam and frame.polarity == "dense-dark"
    res = track_image(frame.pixels, features, frame.camera, polarity_hint="dense_dark")
    assert res.pose.converged
    dr, dt = pose_errors(res.pose.rotation, res.pose.translation_mm, R[0], t[0])
    assert np.degrees(np.linalg.norm(dr)) < 0.5 and np.linalg.norm(dt) < 2.0
