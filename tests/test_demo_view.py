"""The demo's view step (:mod:`ftrac_design.demo.view`): the tie is refused alone and settled
with the view known beforehand, and what it prints is what the pose files say."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from ftrac_design.demo.view import demo_step
from ftrac_design.pose import so3


def test_the_tie_is_refused_alone_and_settled_by_the_expected_view(tmp_path):
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        text = demo_step(Path("view"))
    finally:
        os.chdir(here)
    out = tmp_path / "view"
    alone = json.loads((out / "alone" / "pose.json").read_text())
    with_view = json.loads((out / "with_view" / "pose.json").read_text())
    truth = json.loads((out / "truth.json").read_text())
    R = np.array(truth["rotation"])
    assert not alone["converged"] and alone["error"].startswith("ambiguous identification")
    m = re.search(r"its two answers: ([\d.]+)° and ([\d.]+)° from the true rotation", text)
    assert m, text
    printed = sorted(float(x) for x in m.groups())
    off = sorted(np.degrees(so3.angle(np.array(a["rotation"]), R)) for a in alone["segmentation"]["alternatives"])
    assert np.allclose(printed, off, atol=0.05) and off[0] < 1.0 and off[1] > 100.0
    assert with_view["converged"] and with_view["expected_view"]["within_deg"] == 45.0
    err = np.degrees(so3.angle(np.array(with_view["rotation"]), R))
    assert err < 0.5 and f"rotation {err:.3f}°" in text
    assert "--expect-view view/expected_view.json --view-within-deg 45" in text
