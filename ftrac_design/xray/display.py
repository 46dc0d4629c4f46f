"""The C-arm's image chain: from the quanta reaching the detector to the pixels a user's file holds.

In the order the physics puts them (:func:`apply_chain`):

1. **Collimator blades** (:class:`Shutter` ``blades``): attenuating plates (a few per cent
   transmission, their edges blurred by the penumbra) — they act on the photons, so the
   image under them is dark *and* noisy.
2. **Scatter / veiling glare** (:class:`Detector` ``scatter_fraction``): a low-pass copy of the
   primary (Gaussian, ``scatter_sigma_px``) whose mean is the scatter-to-primary ratio times
   the primary's: 0.3–1 behind a grid, 2–5 without one, for a pelvis.
3. **The image intensifier's round field** (:class:`Shutter` ``round``): only the quanta inside
   the input screen's circle are seen (edge softened over ``edge_px``).
4. **Quantum noise**: Poisson counts; Gaussian with variance N where N ≥ 100 (as
   :mod:`.render` does, per pixel here), exact Poisson draws below.
5. **Detector**: optional blur after the quantum sink (II output phosphor / camera: it
   correlates the noise), the gain field (II vignetting ``1 − v (r/R)²`` and a residual
   flat-field error of ``nonuniformity`` per cent, low-frequency), gain (ADU per quantum),
   dark offset, electronic read noise, rounding and clipping to ``bits`` (the direct beam
   saturates).
6. **Formation** (:class:`Display` ``formation``): ``linear`` — the raw counts (DICOM LIN, dense
   = dark); ``log`` — ``−ln((raw − offset) / (gain N0))``, float32 (LOG, dense = bright, the
   line integral where nothing saturates); ``display`` — what a monitor or a frame grabber
   shows (DISP): the log signal, unsharp-mask edge enhancement ``s + amount (s − G_σ s)``,
   window ``x = clip((s − c + w/2) / w, 0, 1)`` (centre/width given, or from percentiles of
   the exposed patient in the central measuring field), gamma ``y = x^γ``, ``polarity``
   (dense-dark: ``1 − y``), quantised to 8 or 16 bits; outside the round field the lowest value
   (black), with burned-in text and a crosshair when asked, and the frame grabber's analog
   noise.

Every function is pure; settings are frozen dataclasses; bad settings raise
:class:`~ftrac_design.errors.InputError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from scipy.special import ndtr

from ..errors import InputError

Formation = Literal["linear", "log", "display"]
Polarity = Literal["dense-dark", "dense-bright"]
ShutterKind = Literal["none", "round", "blades"]

#: Gaussian draws replace Poisson ones at and above this many expected quanta (skewness ≤ 0.1)
GAUSSIAN_MIN_COUNTS = 100.0
#: log-signal below which a pixel counts as direct beam (air): left out of the automatic window
DIRECT_BEAM = 0.3


def _check(ok: bool, key: str, expected: str) -> None:
    if not ok:
        raise InputError(None, key, expected)


@dataclass(frozen=True)
class Detector:
    """The detector (flat panel or image intensifier + camera) from quanta to raw ADU.

    ``bits`` 12/14/16; ``gain`` ADU per detected quantum; ``offset`` dark level (ADU);
    ``read_noise`` electronic noise σ (ADU); ``nonuniformity`` residual gain error after
    flat-field correction (relative σ of a smooth field, e.g. 0.01 = 1 %); ``scatter_fraction``
    scatter-to-primary ratio (scatter added as a Gaussian low-pass, σ ``scatter_sigma_px``, of
    the primary); ``vignetting`` fractional brightness loss at the field's edge (II: 0.1–0.4);
    ``post_blur_px`` Gaussian σ (px) after the quantum sink (II optics: correlates the noise).
    """

    bits: int = 14
    gain: float = 1.0
    offset: float = 100.0
    read_noise: float = 0.0
    nonuniformity: float = 0.0
    scatter_fraction: float = 0.0
    scatter_sigma_px: float = 60.0
    vignetting: float = 0.0
    post_blur_px: float = 0.0

    def __post_init__(self) -> None:
        _check(self.bits in (12, 14, 16), "Detector.bits", f"12, 14 or 16, got {self.bits!r}")
        _check(self.gain > 0 and math.isfinite(self.gain), "Detector.gain", "a positive number (ADU per quantum)")
        _check(0 <= self.offset < (1 << self.bits), "Detector.offset", "a dark level within the bit depth")
        for key in ("read_noise", "nonuniformity", "scatter_fraction", "post_blur_px"):
            _check(getattr(self, key) >= 0, f"Detector.{key}", "a non-negative number")
        _check(self.scatter_sigma_px > 0, "Detector.scatter_sigma_px", "a positive number (px)")
        _check(0 <= self.vignetting < 1, "Detector.vignetting", "a fraction in [0, 1)")

    @property
    def full_scale(self) -> int:
        """Largest raw value, 2^bits − 1."""
        return (1 << self.bits) - 1


@dataclass(frozen=True)
class Display:
    """How the raw counts become the stored image (see the module).

    ``formation`` linear / log / display; for ``display``: ``window`` (centre, width) in
    line-integral units or None for automatic (``window_percentiles`` of the exposed patient),
    ``gamma``, unsharp mask (``unsharp_sigma_px``, ``unsharp_amount``: high-frequency gain
    1 + amount), ``polarity`` of the output, ``bits`` 8 or 16, burned-in ``annotations``
    (text lines and a crosshair), ``video_noise`` (σ in output grey levels of the 8-bit scale).
    """

    formation: Formation = "display"
    window: tuple[float, float] | None = None
    window_percentiles: tuple[float, float] = (0.5, 99.5)
    gamma: float = 1.0
    unsharp_sigma_px: float = 0.0
    unsharp_amount: float = 0.0
    polarity: Polarity = "dense-dark"
    bits: int = 8
    annotations: bool = False
    video_noise: float = 0.0

    def __post_init__(self) -> None:
        _check(
            self.formation in ("linear", "log", "display"),
            "Display.formation",
            f"linear, log or display, got {self.formation!r}",
        )
        _check(
            self.polarity in ("dense-dark", "dense-bright"),
            "Display.polarity",
            f"dense-dark or dense-bright, got {self.polarity!r}",
        )
        _check(self.bits in (8, 16), "Display.bits", f"8 or 16, got {self.bits!r}")
        _check(self.gamma > 0 and math.isfinite(self.gamma), "Display.gamma", "a positive number")
        _check(
            self.unsharp_sigma_px >= 0 and self.unsharp_amount >= 0,
            "Display.unsharp",
            "a non-negative σ (px) and amount",
        )
        _check(
            self.window is None or (len(self.window) == 2 and self.window[1] > 0),
            "Display.window",
            "None or (centre, width) with a positive width",
        )
        lo, hi = self.window_percentiles
        _check(0 <= lo < hi <= 100, "Display.window_percentiles", "two percentiles 0 ≤ low < high ≤ 100")
        _check(self.video_noise >= 0, "Display.video_noise", "a non-negative number")


@dataclass(frozen=True)
class Shutter:
    """The field's edges: ``none``; ``round`` — an image intensifier's circular field (centre
    (u, v) px, default the image centre; radius px, default 47 % of the shorter side; edge
    softened over ``edge_px``); ``blades`` — collimator plates at ``opening_px`` (left,
    right, top, bottom: distances from the centre in the frame turned by ``angle`` rad; inf:
    no blade on that side), passing ``transmission`` of the photons, edges blurred by a
    Gaussian penumbra of σ ``penumbra_px``."""

    kind: ShutterKind = "none"
    center_px: tuple[float, float] | None = None
    radius_px: float | None = None
    edge_px: float = 1.5
    opening_px: tuple[float, float, float, float] = (math.inf, math.inf, math.inf, math.inf)
    angle: float = 0.0
    transmission: float = 0.04
    penumbra_px: float = 2.0

    def __post_init__(self) -> None:
        _check(self.kind in ("none", "round", "blades"), "Shutter.kind", f"none, round or blades, got {self.kind!r}")
        _check(self.radius_px is None or self.radius_px > 0, "Shutter.radius_px", "a positive radius (px)")
        _check(self.edge_px >= 0 and self.penumbra_px >= 0, "Shutter.edge_px / penumbra_px", "non-negative widths")
        _check(0 <= self.transmission < 1, "Shutter.transmission", "a fraction in [0, 1)")
        _check(
            len(self.opening_px) == 4 and all(o > 0 for o in self.opening_px),
            "Shutter.opening_px",
            "four positive distances (left, right, top, bottom; inf for no blade)",
        )


# ----------------------------------------------------------------------------- the field
def _centre(shape, center_px):
    H, W = shape
    return ((W - 1) / 2, (H - 1) / 2) if center_px is None else (float(center_px[0]), float(center_px[1]))


def round_field(
    shape: tuple[int, int],
    center_px: tuple[float, float] | None = None,
    radius_px: float | None = None,
    edge_px: float = 1.5,
) -> np.ndarray:
    """Weight (H, W) float32 of an image intensifier's round field: 1 inside, 0 outside, a linear
    ramp ``edge_px`` wide centred on the radius (its sum is π r² to well within a pixel ring)."""
    H, W = shape
    cu, cv = _centre(shape, center_px)
    r = 0.47 * min(H, W) if radius_px is None else float(radius_px)
    u = np.arange(W, dtype=np.float32) - np.float32(cu)
    v = np.arange(H, dtype=np.float32)[:, None] - np.float32(cv)
    rho = np.sqrt(u * u + v * v)
    if edge_px <= 0:
        return (rho <= r).astype(np.float32)
    return np.clip((r - rho) / np.float32(edge_px) + 0.5, 0.0, 1.0).astype(np.float32)


def blade_transmission(
    shape: tuple[int, int],
    center_px: tuple[float, float] | None,
    opening_px: tuple[float, float, float, float],
    angle: float = 0.0,
    transmission: float = 0.04,
    penumbra_px: float = 2.0,
) -> np.ndarray:
    """Fraction (H, W) float32 of the photons that pass the collimator blades: per blade
    ``T + (1 − T) Φ(d / σ)`` with d the signed distance (px) into the opening from its edge
    (Φ the normal CDF: a Gaussian penumbra), multiplied over the blades (T² where two overlap)."""
    H, W = shape
    cu, cv = _centre(shape, center_px)
    ca, sa = math.cos(angle), math.sin(angle)
    u = np.arange(W, dtype=np.float32)[None, :] - np.float32(cu)
    v = np.arange(H, dtype=np.float32)[:, None] - np.float32(cv)
    x = u * np.float32(ca) + v * np.float32(sa)
    y = -u * np.float32(sa) + v * np.float32(ca)
    out = np.ones((H, W), np.float32)
    left, right, top, bottom = opening_px
    for d, inf in ((x + left, left), (right - x, right), (y + top, top), (bottom - y, bottom)):
        if math.isinf(inf):
            continue
        inside = ndtr(d / penumbra_px) if penumbra_px > 0 else (d >= 0)
        out *= (transmission + (1.0 - transmission) * inside).astype(np.float32)
    return out


def shutter_maps(shape: tuple[int, int], shutter: Shutter) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(photon transmission, detected-field weight, exposed mask) (H, W) of ``shutter``: the
    blades' transmission (1 elsewhere), the round field's weight (1 elsewhere), and the bool
    mask of the fully exposed field (inside the circle and more than half open under the blades)."""
    ones = np.ones(shape, np.float32)
    if shutter.kind == "round":
        w = round_field(shape, shutter.center_px, shutter.radius_px, shutter.edge_px)
        return ones, w, w >= 0.5
    if shutter.kind == "blades":
        t = blade_transmission(
            shape, shutter.center_px, shutter.opening_px, shutter.angle, shutter.transmission, shutter.penumbra_px
        )
        return t, ones, t >= 0.5 * (1 + shutter.transmission)
    return ones, ones, np.ones(shape, bool)


# ----------------------------------------------------------------------------- detector
def quantum_noise(expected: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Counts (H, W) float32 drawn about ``expected`` quanta: Gaussian with variance N where
    N ≥ :data:`GAUSSIAN_MIN_COUNTS`, exact Poisson draws below."""
    N = np.asarray(expected, np.float32)
    out = N + np.sqrt(np.maximum(N, 0)) * rng.standard_normal(N.shape, dtype=np.float32)
    low = N < GAUSSIAN_MIN_COUNTS
    if low.any():
        out[low] = rng.poisson(np.maximum(N[low], 0)).astype(np.float32)
    return out


def scatter(primary: np.ndarray, fraction: float, sigma_px: float) -> np.ndarray:
    """Scatter (H, W) float32: ``fraction`` × the primary low-passed by a Gaussian of σ
    ``sigma_px`` (edges reflected), so its mean is ``fraction`` × the primary's."""
    if fraction <= 0:
        return np.zeros_like(primary, dtype=np.float32)
    P = np.asarray(primary, np.float32)
    # a wide Gaussian on a 4× smaller image, then back: the same low-pass for a sixteenth of the work
    k = 4 if sigma_px >= 16 and min(P.shape) >= 64 else 1
    small = cv2.resize(P, (P.shape[1] // k, P.shape[0] // k), interpolation=cv2.INTER_AREA) if k > 1 else P
    low = cv2.GaussianBlur(small, (0, 0), sigma_px / k, borderType=cv2.BORDER_REFLECT)
    if k > 1:
        low = cv2.resize(low, (P.shape[1], P.shape[0]), interpolation=cv2.INTER_LINEAR)
    low *= np.float32(P.mean() / max(float(low.mean()), 1e-30))
    return np.float32(fraction) * low


def gain_field(
    shape: tuple[int, int],
    detector: Detector,
    rng: np.random.Generator,
    center_px: tuple[float, float] | None = None,
    radius_px: float | None = None,
) -> np.ndarray:
    """Relative gain (H, W) float32: vignetting ``1 − v (r/R)²`` about the field's centre
    (R its radius, default the half-diagonal) times ``1 + nonuniformity × smooth field``
    (a unit-σ random field with ~100 px correlation)."""
    H, W = shape
    g = np.ones(shape, np.float32)
    if detector.vignetting > 0:
        cu, cv = _centre(shape, center_px)
        R = float(radius_px) if radius_px is not None else 0.5 * math.hypot(H, W)
        u = (np.arange(W, dtype=np.float32) - np.float32(cu)) / np.float32(R)
        v = (np.arange(H, dtype=np.float32)[:, None] - np.float32(cv)) / np.float32(R)
        g *= np.maximum(1.0 - np.float32(detector.vignetting) * (u * u + v * v), 0.05)
    if detector.nonuniformity > 0:
        small = rng.standard_normal((max(H // 64, 2) + 2, max(W // 64, 2) + 2)).astype(np.float32)
        f = cv2.resize(small, (W, H), interpolation=cv2.INTER_CUBIC)
        f = (f - f.mean()) / max(float(f.std()), 1e-12)
        g *= 1.0 + np.float32(detector.nonuniformity) * f
    return g


def detect(expected: np.ndarray, detector: Detector, rng: np.random.Generator, gain_map: np.ndarray) -> np.ndarray:
    """Raw ADU (H, W) float32 (integers, clipped to the bit depth) from expected quanta: noise,
    post-sink blur, gain field × gain, dark offset, read noise."""
    N = quantum_noise(expected, rng)
    if detector.post_blur_px > 0:
        N = cv2.GaussianBlur(N, (0, 0), detector.post_blur_px, borderType=cv2.BORDER_REFLECT)
    raw = N * (gain_map * np.float32(detector.gain)) + np.float32(detector.offset)
    if detector.read_noise > 0:
        raw += np.float32(detector.read_noise) * rng.standard_normal(raw.shape, dtype=np.float32)
    return np.clip(np.rint(raw), 0, detector.full_scale)


# ----------------------------------------------------------------------------- display
def log_signal(raw: np.ndarray, detector: Detector, n0: float) -> np.ndarray:
    """Line-integral estimate ``−ln((raw − offset) / (gain n0))`` (H, W) float32 (dense = bright);
    counts at or below the dark level are taken as half a quantum."""
    q = np.maximum((np.asarray(raw, np.float32) - np.float32(detector.offset)) / np.float32(detector.gain), 0.5)
    return (np.float32(math.log(n0)) - np.log(q)).astype(np.float32)


def unsharp_mask(image: np.ndarray, sigma_px: float, amount: float) -> np.ndarray:
    """``s + amount (s − G_σ s)`` (float32): constant images pass unchanged, detail finer than σ
    is amplified by up to 1 + amount (edges reflected)."""
    s = np.asarray(image, np.float32)
    if sigma_px <= 0 or amount <= 0:
        return s.copy()
    return s + np.float32(amount) * (s - cv2.GaussianBlur(s, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT))


def window_level(s: np.ndarray, centre: float, width: float) -> np.ndarray:
    """``clip((s − (centre − width/2)) / width, 0, 1)`` (float32)."""
    return np.clip((np.asarray(s, np.float32) - np.float32(centre - width / 2)) / np.float32(width), 0.0, 1.0)


def apply_gamma(x: np.ndarray, gamma: float) -> np.ndarray:
    """``x^γ`` of values in [0, 1] (float32)."""
    return np.power(np.asarray(x, np.float32), np.float32(gamma))


def auto_window(s: np.ndarray, mask: np.ndarray, percentiles: tuple[float, float] = (0.5, 99.5)) -> tuple[float, float]:
    """(centre, width) spanning the given percentiles of ``s`` over the measuring field — the
    central half of the image each way, within ``mask``, as a C-arm's automatic brightness
    and contrast measure — leaving out the direct beam (s < :data:`DIRECT_BEAM`) unless that
    leaves under a fifth of it; every fourth pixel each way (the percentiles move by far less
    than a grey level)."""
    H, W = s.shape
    centre = (slice(H // 4, H - H // 4, 4), slice(W // 4, W - W // 4, 4))
    sub = s[centre][mask[centre]]
    if sub.size < 16:
        sub = s[::4, ::4][mask[::4, ::4]]
    if sub.size == 0:
        sub = s[::4, ::4].ravel()
    body = sub[sub >= DIRECT_BEAM]
    if body.size >= 0.2 * sub.size:
        sub = body
    lo, hi = np.percentile(sub, percentiles)
    width = max(float(hi - lo), 1e-3)
    return float(lo) + width / 2, width


_TEXT = (
    "{kv} kV  {ma:.1f} mA",
    "FL {m:02d}:{s:02d}",
    "DAP {dap:.2f} Gy cm2",
    "IMG {i}/{n}",
    "{d:02d}-{mo:02d}-2024 {h:02d}:{mi:02d}",
)


def annotation_mask(shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Burned-in graphics (H, W) float32 in [0, 1]: four to six lines of acquisition text in two
    corners and a thin crosshair near the centre, as a frame grabber captures them."""
    H, W = shape
    m = np.zeros(shape, np.uint8)
    scale = max(H, W) / 1024 * float(rng.uniform(0.7, 1.0))
    fields = {
        "kv": int(rng.integers(60, 110)),
        "ma": float(rng.uniform(0.5, 12)),
        "m": int(rng.integers(0, 10)),
        "s": int(rng.integers(0, 60)),
        "dap": float(rng.uniform(0.1, 30)),
        "i": int(rng.integers(1, 40)),
        "n": 40,
        "d": int(rng.integers(1, 29)),
        "mo": int(rng.integers(1, 13)),
        "h": int(rng.integers(0, 24)),
        "mi": int(rng.integers(0, 60)),
    }
    lines = [t.format(**fields) for t in _TEXT]
    step = int(30 * scale)
    corners = rng.choice(4, 2, replace=False)
    for k, corner in enumerate(corners):
        block = lines[:3] if k == 0 else lines[3:]
        x = int(12 * scale) if corner in (0, 2) else int(W - 280 * scale)
        y0 = int(30 * scale) if corner in (0, 1) else int(H - step * len(block))
        for j, text in enumerate(block):
            cv2.putText(
                m,
                text,
                (x, y0 + j * step),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.8 * scale,
                255,
                max(1, int(2 * scale)),
                cv2.LINE_AA,
            )
    cu, cv = int(W / 2 + rng.normal(0, W / 20)), int(H / 2 + rng.normal(0, H / 20))
    arm, gap = int(rng.uniform(20, 60) * scale), int(6 * scale)
    for du, dv in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        cv2.line(m, (cu + du * gap, cv + dv * gap), (cu + du * arm, cv + dv * arm), 255, 1, cv2.LINE_AA)
    return m.astype(np.float32) / 255.0


def _display(
    s: np.ndarray, field: np.ndarray, exposed: np.ndarray, display: Display, rng: np.random.Generator
) -> tuple[np.ndarray, dict[str, Any]]:
    """The display formation of a log signal (see the module): stored image and its settings."""
    # outside the field the signal is meaningless: the inside's median there keeps the
    # unsharp mask from ringing along the field's edge
    if not exposed.all():
        s = np.where(field >= 0.5, s, np.float32(np.median(s[::4, ::4][exposed[::4, ::4]]) if exposed.any() else 0))
    s = unsharp_mask(s, display.unsharp_sigma_px, display.unsharp_amount)
    centre, width = (
        display.window if display.window is not None else auto_window(s, exposed, display.window_percentiles)
    )
    y = apply_gamma(window_level(s, centre, width), display.gamma)
    if display.polarity == "dense-dark":
        y = 1.0 - y
    y *= field  # black outside the round field, in either polarity
    top = (1 << display.bits) - 1
    out = y * np.float32(top)
    if display.annotations:
        a = annotation_mask(s.shape, rng)
        out = out * (1 - a) + np.float32(top * float(rng.uniform(0.8, 1.0))) * a
    if display.video_noise > 0:
        out += np.float32(display.video_noise * top / 255.0) * rng.standard_normal(out.shape, dtype=np.float32)
    out = np.clip(np.rint(out), 0, top).astype(np.uint8 if display.bits == 8 else np.uint16)
    return out, {
        "window": (centre, width),
        "gamma": display.gamma,
        "unsharp": (display.unsharp_sigma_px, display.unsharp_amount),
        "annotations": display.annotations,
    }


def apply_chain(
    expected_counts: np.ndarray | None = None,
    detector: Detector = Detector(),
    display: Display = Display(),
    shutter: Shutter = Shutter(),
    rng: np.random.Generator | None = None,
    *,
    line_integral: np.ndarray | None = None,
    n0: float | None = None,
) -> tuple[np.ndarray, dict]:
    """The image a C-arm stores for expected primary quanta per pixel (see the module).

    Parameters
    ----------
    expected_counts : (H, W) noise-free quanta per pixel reaching the detector (blurred by
        the optics already); or give ``line_integral`` (H, W) and ``n0`` (quanta per pixel
        with nothing in the beam) for ``n0 × exp(−line_integral)``.
    detector, display, shutter : the chain's settings.
    rng : draws the noise, the gain field and the annotations (default: a fresh generator).
    n0 : the flat-field reference of the log (quanta per pixel with nothing in the beam);
        default the largest expected count.

    Returns
    -------
    (image, info): the image as stored — uint16 raw ADU (linear), float32 line integral
    (log), uint8/uint16 (display) — and ``info`` with ``formation``, ``polarity``,
    ``field_mask`` (bool (H, W), True = exposed), ``exposed_fraction``, ``n0``, ``gain``,
    ``offset``, ``bits``, ``saturated_fraction`` and for display ``window`` (centre, width),
    ``gamma``, ``unsharp`` (σ px, amount), ``annotations``.
    """
    if expected_counts is None:
        if line_integral is None or n0 is None:
            raise InputError(None, "expected_counts", "expected counts, or a line integral with n0")
        expected_counts = np.float32(n0) * np.exp(-np.asarray(line_integral, np.float32))
    N = np.asarray(expected_counts, np.float32)
    _check(
        N.ndim == 2 and bool(np.isfinite(N).all()) and float(N.min()) >= 0,
        "expected_counts",
        "a 2-D array of finite non-negative quanta per pixel",
    )
    rng = rng if rng is not None else np.random.default_rng()
    n0 = float(N.max()) if n0 is None else float(n0)
    _check(n0 > 0, "n0", "a positive number of quanta per pixel")
    blades, field, exposed = shutter_maps(N.shape, shutter)
    primary = N * blades
    total = (primary + scatter(primary, detector.scatter_fraction, detector.scatter_sigma_px)) * field
    gains = gain_field(
        N.shape,
        detector,
        rng,
        shutter.center_px if shutter.kind == "round" else None,
        shutter.radius_px if shutter.kind == "round" else None,
    )
    raw = detect(total, detector, rng, gains)
    info: dict[str, Any] = {
        "formation": display.formation,
        "field_mask": exposed,
        "exposed_fraction": float(exposed.mean()),
        "n0": n0,
        "gain": detector.gain,
        "offset": detector.offset,
        "bits": detector.bits,
        "saturated_fraction": float((raw >= detector.full_scale).mean()),
        "shutter": shutter.kind,
    }
    if display.formation == "linear":
        info["polarity"] = "dense-dark"
        return raw.astype(np.uint16), info
    s = log_signal(raw, detector, n0)
    if display.formation == "log":
        info["polarity"] = "dense-bright"
        return s, info
    out, extra = _display(s, field, exposed, display, rng)
    info.update(extra, polarity=display.polarity, bits=display.bits)
    return out, info


def n0_for_counts(
    background: np.ndarray,
    counts_behind_patient: float,
    statistic: Literal["median", "mean"] = "median",
    mask: np.ndarray | None = None,
    threshold: float = 0.5,
) -> float:
    """Quanta per pixel with nothing in the beam (N0) that put ``counts_behind_patient`` behind
    the patient, as automatic exposure control sets the dose (100–500 quanta per pixel in
    fluoroscopy, a few thousand in a radiograph).

    ``background`` (H, W) is the patient's line integral; "behind the patient" is ``mask``
    (bool) or, by default, where the line integral exceeds ``threshold`` (more than ~25 mm
    of tissue: the air beside the patient is left out). ``statistic`` median: the median of
    ``N0 exp(−background)`` there equals the asked counts; mean: its mean does.
    """
    _check(counts_behind_patient > 0, "counts_behind_patient", "a positive number of quanta per pixel")
    _check(statistic in ("median", "mean"), "statistic", f"median or mean, got {statistic!r}")
    bg = np.asarray(background, np.float64)
    sel = bg[mask] if mask is not None else bg[bg > threshold]
    if sel.size == 0:
        sel = bg.ravel()
    t = np.exp(-sel)
    ref = float(np.median(t) if statistic == "median" else np.mean(t))
    return float(counts_behind_patient) / ref
