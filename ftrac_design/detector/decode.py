"""The network's maps turned into what the tracker reads: ball candidates with sub-pixel
positions, strongest first, and the wire probability anywhere in the image.

Output channels, per cell of ``STRIDE`` working pixels: 0 the ball logit, 1–2 the ball centre's
offset (working px, u then v) from the cell's centre, 3 the wire logit, 4–5 the wire's direction
as (cos 2θ, sin 2θ) (a direction without a sense). Image coordinates follow SPEC §1: pixel
(i, j) is centred at (u, v) = (i, j); a working pixel k covers image pixels s·k … s·k + s − 1,
so it is centred at s·k + (s − 1)/2.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .normalise import STRIDE

#: output channels of the network, in order
CHANNELS = ("ball", "ball_du", "ball_dv", "wire", "wire_cos2", "wire_sin2")


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return (0.5 * (1.0 + np.tanh(0.5 * x))).astype(np.float32)


@dataclass(frozen=True)
class Detections:
    """What the detector found in one image.

    Attributes
    ----------
    beads_uv : (n, 2) ndarray
        Ball centres (px of the image), most probable first.
    beads_score : (n,) ndarray
        Their probabilities (0–1).
    ball : (h, w) ndarray
        Ball probability per output cell.
    wire : (h, w) ndarray
        Wire probability per output cell.
    wire_dir : (h, w, 2) ndarray
        The wire's direction per cell as (cos 2θ, sin 2θ), θ from the u axis.
    scale : int
        The working scale (image px per working px).
    shape : (int, int)
        The image's (H, W).
    """

    beads_uv: np.ndarray
    beads_score: np.ndarray
    ball: np.ndarray
    wire: np.ndarray
    wire_dir: np.ndarray
    scale: int
    shape: tuple[int, int]

    @property
    def cell_px(self) -> int:
        """Side of an output cell in image pixels."""
        return self.scale * STRIDE

    def to_cell(self, uv: np.ndarray) -> np.ndarray:
        """Image points ``uv`` (n, 2) in output-cell coordinates (cell (c, r) centred at (c, r))."""
        s = self.scale
        return ((np.asarray(uv, float) - (s - 1) / 2) / s - 0.5) / STRIDE

    def wire_probability(self, uv: np.ndarray) -> np.ndarray:
        """The wire probability at image points ``uv`` (n, 2) px, bilinear between cells (0 outside)."""
        return bilinear(self.wire, self.to_cell(uv))

    def ball_probability(self, uv: np.ndarray) -> np.ndarray:
        """The largest ball probability of the cells around image points ``uv`` (n, 2) px (the
        map peaks on the cell nearest a ball's centre)."""
        c = np.rint(self.to_cell(uv)).astype(np.int64)
        h, w = self.ball.shape
        best = np.zeros(len(c))
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                r, q = c[:, 1] + dr, c[:, 0] + dc
                ok = (r >= 0) & (r < h) & (q >= 0) & (q < w)
                best[ok] = np.maximum(best[ok], self.ball[r[ok], q[ok]])
        return best

    def crop(self, r0: int, c0: int) -> "Detections":
        """The same detections in the coordinates of a crop whose corner is image pixel (r0, c0)
        (ball positions shifted; the maps are still looked up through :meth:`wire_probability`
        of the whole image)."""
        return CroppedDetections(self, r0, c0)


class CroppedDetections:
    """:class:`Detections` seen from a crop of the image (corner at image pixel (r0, c0))."""

    def __init__(self, parent: Detections, r0: int, c0: int):
        self.parent, self.r0, self.c0 = parent, r0, c0
        self.beads_uv = parent.beads_uv - np.array([c0, r0], float)
        self.beads_score = parent.beads_score

    def wire_probability(self, uv: np.ndarray) -> np.ndarray:
        """The wire probability at crop points ``uv`` (n, 2) px."""
        return self.parent.wire_probability(np.asarray(uv, float) + np.array([self.c0, self.r0], float))

    def ball_probability(self, uv: np.ndarray) -> np.ndarray:
        """The ball probability at crop points ``uv`` (n, 2) px."""
        return self.parent.ball_probability(np.asarray(uv, float) + np.array([self.c0, self.r0], float))

    def crop(self, r0: int, c0: int) -> "CroppedDetections":
        """A crop of this crop."""
        return CroppedDetections(self.parent, self.r0 + r0, self.c0 + c0)


def bilinear(grid: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """``grid`` (h, w) at fractional (column, row) points ``xy`` (n, 2), bilinear with exact
    weights, 0 beyond the grid (a zero border)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    h, w = grid.shape
    flat = np.concatenate([np.asarray(grid, float).reshape(-1), [0.0]])
    x0, y0 = np.floor(xy[:, 0]), np.floor(xy[:, 1])
    fx, fy = xy[:, 0] - x0, xy[:, 1] - y0
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    out = np.zeros(len(xy))
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            xi, yi = x0 + dx, y0 + dy
            idx = np.where((xi >= 0) & (xi < w) & (yi >= 0) & (yi < h), yi * w + xi, h * w)
            out += flat[idx] * wx * wy
    return out


def decode(
    maps: np.ndarray, scale: int, shape: tuple[int, int], max_beads: int = 64, min_score: float = 0.05
) -> Detections:
    """:class:`Detections` from the network's output ``maps`` (6, h, w) for an image of ``shape``.

    Ball candidates are the cells whose probability is the largest of their 3 × 3 neighbours and
    at least ``min_score``, at most ``max_beads``, most probable first, placed by their
    offsets; candidates outside the image are dropped.
    """
    ball = _sigmoid(maps[0])
    peak = (ball >= cv2.dilate(ball, np.ones((3, 3), np.uint8))) & (ball >= min_score)
    r, c = np.nonzero(peak)
    score = ball[r, c]
    order = np.argsort(-score, kind="stable")[:max_beads]
    r, c, score = r[order], c[order], score[order]
    wu = STRIDE * c + 0.5 + maps[1, r, c]
    wv = STRIDE * r + 0.5 + maps[2, r, c]
    uv = np.stack([scale * wu + (scale - 1) / 2, scale * wv + (scale - 1) / 2], -1).astype(float)
    H, W = shape
    inside = (uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] <= H - 1)
    d = maps[4:6].transpose(1, 2, 0)
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    return Detections(
        uv[inside],
        score[inside].astype(float),
        ball,
        _sigmoid(maps[3]),
        d / np.maximum(n, 1e-6),
        scale,
        (int(H), int(W)),
    )
