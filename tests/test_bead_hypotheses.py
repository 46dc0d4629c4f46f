"""The bead hypotheses of a small fiducial seen in near-affine projection.

ftrac_mini is 1 × 1 × 2 cm at about 650 mm from the source: three of its balls give P3P two
poses tens of degrees apart that both put every other ball on the same blob. Both must stay
hypotheses; the right pose kept only when its RMS was the lower lost it to its twin, and a
labelling 178° off was then given out with confidence (``sequence_speed.py``'s ftrac_mini
run over anatomy, frames 85, 88 and 93)."""

from __future__ import annotations

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, so3
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import identify

#: the sequence benchmark's camera: 1000 mm source to detector, 0.44 mm pixels
CAMERA = Camera(1000.0, (0.44, 0.44), (511.5, 511.5))


@pytest.fixture(scope="module")
def views():
    """200 views of ftrac_mini, seven of its nine balls seen at 0.15 px of noise each: the
    model, the truth (R, t), the blobs and the true labelling (model ball → blob)."""
    f = compute_features(load_design("ftrac_mini"))
    model = f.point_centers()
    R, t = Workspace(cone_deg=10.0, lateral_mm=10.0).sample(200, f.nominal_beam_direction, np.random.default_rng(5))
    rng = np.random.default_rng(6)
    out = []
    for k in range(len(R)):
        uv = identify.project(CAMERA, R[k], t[k], model)[0]
        seen = np.sort(rng.permutation(len(model))[:7])
        blobs = uv[seen] + rng.normal(0.0, 0.15, (len(seen), 2))
        out.append((model, R[k], t[k], blobs, {int(m): i for i, m in enumerate(seen)}))
    return out


def test_the_true_labelling_keeps_a_pose_near_the_truth(views):
    """In every view the true labelling is a hypothesis with a pose within 10° of the truth,
    the P3P twin beside it where there is one (before: 2 of these 200 kept the twin alone,
    111° and 129° off)."""
    twins = 0
    for model, R, _t, blobs, truth in views:
        hyps = [h for h in identify.bead_hypotheses(model, blobs, CAMERA, 2.0, keep=None) if h.match == truth]
        off = [float(so3.angle(h.R, R)) for h in hyps]
        assert min(off) < np.radians(10.0)
        twins += len(hyps) > 1
    # the case exists in this set: some true labellings come with two poses
    assert twins >= 3


def test_poses_kept_for_one_labelling_are_distinct(views):
    """Two hypotheses of one labelling are never closer than ``SAME_POSE_RAD``: the noise of
    one P3P pose from triplet to triplet does not multiply the hypotheses."""
    for model, _R, _t, blobs, _truth in views[:60]:
        hyps = identify.bead_hypotheses(model, blobs, CAMERA, 2.0, keep=None)
        by_labelling: dict[tuple, list] = {}
        for h in hyps:
            by_labelling.setdefault(tuple(sorted(h.match.items())), []).append(h.R)
        for Rs in by_labelling.values():
            for i in range(len(Rs)):
                for j in range(i):
                    assert so3.angle(Rs[i], Rs[j]) >= identify.SAME_POSE_RAD
