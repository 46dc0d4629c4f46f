"""The segmentation's shortcuts give what the plain computation gives:
the blob peaks tested only at strong pixels equal those of a whole-image dilation, and the
remembered contour fits and residuals equal fresh ones."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ftrac_design.pose.fitting import fit_conic, fit_line
from ftrac_design.segment.beads import blob_candidates
from ftrac_design.segment.image import gaussian_kernels
from ftrac_design.segment.noise import cached_fit


def _blob_candidates_dense(img, radius_px, noise, max_count, min_snr):
    """The peak search with cv2.dilate over the whole image (the former implementation)."""
    sb = max(radius_px / np.sqrt(2.0), 0.8)
    g0, _, g2 = gaussian_kernels(sb)
    xx = cv2.sepFilter2D(img, cv2.CV_32F, g2, g0, borderType=cv2.BORDER_REPLICATE)
    yy = cv2.sepFilter2D(img, cv2.CV_32F, g0, g2, borderType=cv2.BORDER_REPLICATE)
    resp = -(xx + yy) * (sb * sb)
    nr = noise * sb * sb * float(np.sqrt(2 * (g2.astype(float) ** 2).sum() * (g0.astype(float) ** 2).sum()))
    k = max(int(round(radius_px)), 1)
    dil = cv2.dilate(resp, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1)))
    j, i = np.nonzero((resp >= dil) & (resp > min_snr * nr) & (xx < 0) & (yy < 0))
    val = resp[j, i]
    o = np.argsort(-val)[:max_count]
    return np.stack([i[o], j[o]], -1).astype(float), val[o] / nr


@pytest.mark.parametrize("seed", range(12))
def test_blob_peaks_equal_whole_image_dilation(seed):
    rng = np.random.default_rng(seed)
    img = rng.normal(size=(120, 150)).astype(np.float32)
    for _ in range(8):  # blobs, some at the border, some touching
        y, x = rng.integers(0, 120), rng.integers(0, 150)
        img[max(y - 3, 0) : y + 3, max(x - 3, 0) : x + 3] += rng.uniform(3, 20)
    r = float(rng.uniform(1.5, 6))
    snr = float(rng.choice([0.1, 2.0, 8.0]))  # 0.1: most pixels strong, the dilation path
    a = blob_candidates(img, r, 1.0, 40, snr, min_isotropy=0.0)
    b = _blob_candidates_dense(img, r, 1.0, 40, snr)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_remembered_fits_equal_fresh_ones():
    rng = np.random.default_rng(1)
    s = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    pts = np.stack([30 * np.cos(s) + 5, 18 * np.sin(s) - 2], -1) + rng.normal(0, 0.1, (40, 2))
    for fitter in (fit_conic, fit_line):
        f1, f2 = cached_fit(fitter, pts), cached_fit(fitter, pts.copy())
        assert f1 is f2  # same points: remembered
        g = fitter(pts)
        assert float(f1.rss) == float(g.rss) and int(f1.dof) == int(g.dof)
    moved = pts + 0.5
    assert float(cached_fit(fit_conic, moved).rss) == float(fit_conic(moved).rss)
