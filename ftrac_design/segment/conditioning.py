"""From the pixels as stored to the density image the detectors work on, and where the image
can be read at all.

Images come in three formations: **linear** detector counts (dense = dark; the log of the
Beer–Lambert law makes a ball's contrast the same over any background), **log** /
line-integral images (linear in density already) and **display**-processed frames (window,
gamma, edge enhancement, 8 bits: a monotone map of either, in either polarity). Only linear
counts are logged: a display frame's black-clipped pixels would become −ln 0, and its gamma
is locally a gain that the local noise map (:func:`.image.noise_map`) takes out anyway.

Where an image holds no information — outside a round image-intensifier field or behind a
collimator that clipped it to black, in saturated or black-clipped regions of a display
frame — it is marked *invalid*: regions of pixels at the image's extreme values that are
wider than a ball (an opening with the top-hat's disc keeps balls and wires that happen to
be clipped), grown by a margin so that the field edge's blur and edge-enhancement overshoot
are left out too. Nothing is detected there, and a feature predicted there counts neither
for nor against a labelling.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

Formation = Literal["linear", "log", "display"]
FORMATIONS: tuple[str, ...] = ("linear", "log", "display")


#: the fewest pixels at the dense side's extreme that make it a clip: a raw frame's darkest
#: pixel, alone or one of a few (a ball's centre, often), is a measurement, not a censored one
MIN_CLIPPED_PX = 16


@dataclass(frozen=True)
class Conditioned:
    """A density image (float32, dense = bright) and where it is valid."""

    density: np.ndarray
    #: True where the image holds information; None: everywhere
    valid: np.ndarray | None
    polarity: str
    formation: str
    #: True where the pixel shows nothing of what lies there (:attr:`Cleaned.hidden`); None: nowhere
    hidden: np.ndarray | None = None
    #: True where the pixel is clipped on the dense side (the frame's lowest value for a
    #: dense-dark image, its highest for a dense-bright one): what lies there is at least as
    #: dense as the pixel shows; None: nowhere
    censored: np.ndarray | None = None


def formation_of(image: np.ndarray, polarity: str, hint: str | None = None) -> str:
    """The formation of ``image``: ``hint`` when given (a header's LIN / LOG / DISP), else
    "display" for 8-bit pixel values (0–255 integers: what a frame grabber or a screen
    capture holds), else "linear" for a dense-dark image (raw counts) and "log" for a
    dense-bright one."""
    if hint in FORMATIONS:
        return str(hint)
    a = np.asarray(image)
    if a.size and float(a.min()) >= 0 and float(a.max()) <= 255:
        if np.issubdtype(a.dtype, np.integer) or bool(np.all(a == np.round(a))):
            return "display"
    return "linear" if polarity == "dense-dark" else "log"


def to_density(image: np.ndarray, polarity: str, formation: str = "linear") -> np.ndarray:
    """The density image (float32, dense = bright) of ``image`` of known ``polarity``
    ("dense-dark" / "dense-bright") and ``formation`` (see :func:`formation_of`): linear
    dense-dark counts are logged (−ln), everything else is used as it is or negated."""
    img = np.asarray(image, dtype=np.float32)
    if polarity not in ("dense-dark", "dense-bright"):
        raise ValueError(f"polarity must be dense-dark or dense-bright, got {polarity!r}")
    if formation == "linear" and polarity == "dense-dark":
        lo = max(float(img.max()) * 1e-5, 1e-6)
        return -cv2.log(np.maximum(img, np.float32(lo)))
    if polarity == "dense-bright":
        return img
    return -img


def invalid_regions(
    image: np.ndarray, disc_px: int, margin_px: int, levels: tuple[float, float] | None = None
) -> np.ndarray | None:
    """Pixels that hold no information (bool, True = invalid), or None when there are none:
    regions pinned at the image's lowest or highest value (clipped: a shutter, black outside a
    round field, a saturated direct beam, a display window's white or black) wider than the
    disc of radius ``disc_px``, grown by ``margin_px``.

    A display frame's clipped region is noisy around its clip level (quantisation, analogue
    video noise), so it is found on the 5 × 5 mean: within 2 % of the range of an extreme (a
    raw or log image: exactly at it). Holes up to ~24 px across that it encloses — burned-in
    text and graphics over a saturated corner — are filled: they carry no anatomy either
    (:func:`_closed_where_wide`; a gap open to the rest of the image is not a hole). Only a
    clipped region that is itself wider than the disc is filled so: where a window maps dense
    anatomy near black, the dense balls over it are clipped cores a few px wide, and closing
    those of balls closer than ~24 px alone would join them into one region wider than a
    ball, taking the balls and their readable flanks out of the image (ftrac_2005 over the
    spine, six hard conditions of the realism benchmark: 48 of 360 images would lose 1–7 of
    their 9 balls so).

    ``levels``: the (lowest, highest) pixel value of the whole frame when ``image`` is a crop
    of it (a crop's own extremes are not the frame's clip levels)."""
    a = np.asarray(image, dtype=np.float32)
    lo, hi = (float(a.min()), float(a.max())) if levels is None else (float(levels[0]), float(levels[1]))
    if not hi > lo:
        return None
    display = hi - lo <= 255.0
    tol = 0.02 * (hi - lo) if display else 0.0
    m = cv2.blur(a, (5, 5)) if display else a
    ext = ((m <= lo + tol) | (m >= hi - tol)).astype(np.uint8)
    if ext.sum() < (2 * disc_px + 1) ** 2:
        return None
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * disc_px + 1, 2 * disc_px + 1))
    if display:
        wide = cv2.morphologyEx(ext, cv2.MORPH_OPEN, k)
        region, filled = _closed_where_wide(ext, wide, disc_px)
        # every disc inside ``ext`` lies in one of its parts, and that part holds a pixel of
        # ``wide``: with no hole filled the region's opening is ``wide`` itself (one 17–25 px
        # opening of the frame less: a fifth of this call's time on a 1024² display frame)
        ext = cv2.morphologyEx(region, cv2.MORPH_OPEN, k) if filled else wide
    else:
        ext = cv2.morphologyEx(ext, cv2.MORPH_OPEN, k)
    if not ext.any():
        return None
    mk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1, 2 * margin_px + 1))
    return cv2.dilate(ext, mk).astype(bool)


def _closed_where_wide(ext: np.ndarray, wide: np.ndarray, disc_px: int) -> tuple[np.ndarray, bool]:
    """The regions of ``ext`` (uint8 0/1) that hold a pixel of ``wide`` (``ext`` opened with a
    disc of radius ``disc_px``), with the holes they enclose filled where a 25 px disc's closing
    fills them: text over a saturated corner goes with the corner, while clipped specks that
    are all narrower than a ball, and ball cores clipped beside a wide region, are not joined
    to it.

    Only enclosed holes are filled: where a window clips the anatomy beside the fiducial, a
    closing also bridged the clipped cores of the balls a few px off the region's edge into
    it, and took the balls with their readable flanks out of the image (a ftrac_2005 display
    frame of seed 2061, its balls' cores at 255 and their flanks at 200–240: refused, no ball
    left to fit).

    Returns the regions (uint8 0/1) and whether a hole was filled: where none was, they are
    the parts of ``ext`` holding ``wide``, whose opening is ``wide`` itself."""
    if not wide.any():
        return wide, False
    n, lab = cv2.connectedComponents(ext)
    keep = np.zeros(n, bool)
    # every part of ``wide`` holds a whole disc of radius disc_px, hence a square of side
    # √2·disc_px, hence a pixel of the grid of step disc_px: the grid finds every region
    # that holds one (reading all ~10⁶ labels cost 6 ms of a frame's 20)
    s = max(int(disc_px), 1)
    keep[lab[::s, ::s][wide[::s, ::s] > 0]] = True
    keep[0] = False
    region = keep[lab].astype(np.uint8)
    # a hole is a part of the rest that does not reach the frame's edge (4-connected: a
    # diagonal gap in the region's outline lets nothing through)
    m, rest = cv2.connectedComponents(1 - region, connectivity=4)
    outside = np.zeros(m, bool)
    outside[np.unique(np.r_[rest[0], rest[-1], rest[:, 0], rest[:, -1]])] = True
    outside[0] = True
    hole = ~outside[rest]
    if not hole.any():
        return region, False
    # the closing at a pixel reads the region within 2 × 12 px of it: closed on the holes'
    # box grown by 25 px, the holes get what a closing of the whole frame gives them, for a
    # fraction of its cost (a 1024² frame's closing took ~30 ms; most frames have no hole)
    rows, cols = np.nonzero(hole)
    H, W = region.shape
    r0, r1 = max(int(rows.min()) - 25, 0), min(int(rows.max()) + 26, H)
    c0, c1 = max(int(cols.min()) - 25, 0), min(int(cols.max()) + 26, W)
    box = region[r0:r1, c0:c1]
    closed = cv2.morphologyEx(box, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (25, 25)))
    fill = (closed > 0) & (box == 0) & hole[r0:r1, c0:c1]
    box[fill] = 1
    return region, bool(fill.any())


def _at_extremes(
    a: np.ndarray, levels: tuple[float, float] | None
) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
    """The pixels of ``a`` (any real dtype) at its highest and at its lowest value — within 1 % of the
    range for 0–255 images (a display frame's noise around its clip level), exactly otherwise
    — or (None, None) for a constant image. ``levels``: as for :func:`invalid_regions`."""
    lo, hi = (float(a.min()), float(a.max())) if levels is None else (float(levels[0]), float(levels[1]))
    if not hi > lo:
        return None, None
    tol = 0.01 * (hi - lo) if hi - lo <= 255.0 else 0.0
    return a >= hi - tol, a <= lo + tol


#: how far (px) and how many times :func:`fill_clipped` reaches out for unclipped values
FILL_RADIUS_PX, FILL_PASSES = 2, 2


def fill_clipped(
    image: np.ndarray,
    radius_px: int = FILL_RADIUS_PX,
    passes: int = FILL_PASSES,
    levels: tuple[float, float] | None = None,
) -> np.ndarray:
    """``image`` (float32) with its pixels at the extreme values (within 1 % of the range of
    the lowest or highest, for 0–255 images; exactly, otherwise) replaced by the nearest
    unclipped values: a high pixel by the highest unclipped pixel within ``radius_px``, a low
    one by the lowest, ``passes`` times outward.

    A frame grabber's burned-in text, crosshairs and rulers are strokes 1–3 px wide at the
    display's extreme value with no blur; they were the strongest blobs in the image (their
    contrast against black air is many times a ball's against a patient) and took every
    candidate slot and the region search. Filled in, they vanish into the background around
    them, while a ball or a wire whose core the window clipped keeps its blurred flanks and
    becomes flat-topped. ``levels``: as for :func:`invalid_regions`."""
    a = np.array(image, dtype=np.float32, copy=True)
    high, low = _at_extremes(a, levels)
    return a if high is None else _filled(a, high, low, radius_px, passes)


def _filled(a: np.ndarray, high: np.ndarray, low: np.ndarray, radius_px: int, passes: int) -> np.ndarray:
    """:func:`fill_clipped` of the float32 image ``a`` (filled in place and returned), its
    clipped pixels ``high`` and ``low`` given."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1, 2 * radius_px + 1))
    for sign, clip in ((1.0, high), (-1.0, low)):
        todo = clip.copy()
        for _ in range(passes):
            if not todo.any():
                break
            # OpenCV's dilation saturates −inf to −FLT_MAX: a finite sentinel is tested instead
            src = np.where(todo, np.float32(-1e30), sign * a).astype(np.float32)
            near = cv2.dilate(src, k)
            got = todo & (near > -1e29)
            a[got] = sign * near[got]
            todo &= ~got
    return a


#: a burned-in stroke stands this far above (or below) what a 7 × 7 opening leaves of the
#: pixels around it, as a fraction of the frame's range: text and crosshairs are drawn at
#: high contrast, and the noise of a display frame's anatomy rarely reaches it
_STROKE_CONTRAST = 0.15
#: a grey level is the graphics' when the stroke pixels within ±1 of it are at least this many
#: times as frequent as at the levels 4–15 away, and at least ``_STROKE_MIN_PX`` of them
_SPIKE_RATIO = 6.0
_STROKE_MIN_PX = 60
#: crest pixels at the graphics' level a 9 × 9 window around one of them holds at least (a
#: 1-px crosshair arm through it: 9)
_RUN_PX = 6
#: grey levels a neighbour of a stroke's crest may exceed it by (the frame grabber's noise)
_CREST_LEVELS = 6


def burned_in_graphics(image: np.ndarray, levels: tuple[float, float] | None = None) -> np.ndarray | None:
    """Pixels of burned-in graphics in a display frame (bool, True = graphics), or None when
    none is found: the crests of thin strokes (at least ``_STROKE_CONTRAST`` of the range above
    or below a 7 × 7 opening of the frame, no neighbour beyond them by more than
    ``_CREST_LEVELS``) whose grey level is a spike in those crests' histogram.

    A frame grabber writes its text and crosshair at one grey level (plus the video noise),
    often not the display's extreme (which :func:`fill_clipped` takes out): there they stayed,
    and letters and the gaps between them read as balls (nine_bead on a display frame of
    seed 2060: seven "balls" on the text in a corner, a pose 89° and 284 mm off at
    χ²₆ 13,839). Anatomy, balls and wires have no one level: their strokes spread over the
    histogram, and a 0.5 mm wire over a flat background is blurred across many levels.

    ``levels``: the whole frame's (lowest, highest) pixel value when ``image`` is a crop."""
    a = np.asarray(image, dtype=np.float32)
    lo, hi = (float(a.min()), float(a.max())) if levels is None else (float(levels[0]), float(levels[1]))
    span = int(round(hi - lo))
    sample = a[::7, ::7]
    if not 0 < span <= 255 or not np.array_equal(sample, np.round(sample)):
        # graphics are written into 8-bit frames; a log image's values are not grey levels
        return None
    q = cv2.convertScaleAbs(a, alpha=1.0, beta=-lo)  # rounded and saturated to 0…255
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    # the extremes (within 1 % of the range) are fill_clipped's; 1 level more for the ±1 window
    window = (int(0.01 * span) + 2, span - int(0.01 * span) - 2)
    strokes = np.zeros(a.shape, bool)
    box = np.ones((3, 3), np.uint8)
    for sign, beside in ((1, cv2.dilate(q, box) - q), (-1, q - cv2.erode(q, box))):
        hat = cv2.morphologyEx(q, cv2.MORPH_TOPHAT if sign > 0 else cv2.MORPH_BLACKHAT, k)
        strokes |= _strokes_at_a_level(q, hat, beside, sign, span, window)
    return strokes if strokes.any() else None


def _strokes_at_a_level(
    q: np.ndarray, hat: np.ndarray, beside: np.ndarray, sign: int, span: int, window: tuple[int, int]
) -> np.ndarray:
    """:func:`burned_in_graphics` for strokes brighter (``sign`` 1) or darker (−1) than around
    them: ``q`` the frame's grey levels (uint8, from its lowest), ``hat`` its top-hat (black
    top-hat), ``beside`` how far a neighbour exceeds each pixel the other way, the spike's
    level looked for within ``window``."""
    thin = hat >= _STROKE_CONTRAST * span
    # a stroke's crest: nothing beside it brighter (darker) by more than the video noise; a
    # ball's or a vessel's flank crossing the graphics' level has its brighter core beside it
    stroke = thin & (beside <= _CREST_LEVELS)
    h = np.bincount(q[stroke], minlength=256).astype(float)
    s3 = np.convolve(h, np.ones(3), "same")
    # per level, the median count at the levels 4–15 below and above it
    win = np.lib.stride_tricks.sliding_window_view(np.pad(h, 15, mode="edge"), 31)[:, np.r_[0:12, 19:31]]
    base = np.maximum(np.median(win, axis=1), 1.0)
    peak = (s3 >= _STROKE_MIN_PX) & (s3 >= np.roll(s3, 1)) & (s3 >= np.roll(s3, -1)) & (s3 >= _SPIKE_RATIO * 3 * base)
    peak[: max(window[0], 1)] = peak[window[1] :] = False
    if not peak.any():
        return np.zeros(q.shape, bool)
    x = np.flatnonzero(peak)
    near = np.zeros(256, bool)
    near[np.clip((x[:, None] + np.arange(-2, 3)).ravel(), 0, 255)] = True
    level = (stroke & near[q]).astype(np.float32)
    # graphics are runs of strokes, all at their level; a vessel's wall or a wire's crest that
    # happens to cross it is a pixel or two, among crests at other levels
    n_level = cv2.boxFilter(level, -1, (9, 9), normalize=False)
    n_stroke = cv2.boxFilter(stroke.astype(np.float32), -1, (9, 9), normalize=False)
    found = (level > 0) & (n_level >= 0.5 * n_stroke) & (n_level >= _RUN_PX)
    # and the rest of each glyph, grown along its strokes: a slash or a letter's diagonal is
    # anti-aliased all along, with no pixel at the level, and left in it became a bright smear
    # when the strokes around it were filled in. A pixel joins where it covers 40 % of the
    # way from what is around it to the level (noise beside a stroke does not).
    top = float(x[np.argmax(s3[x])])
    ground = q.astype(np.float32) - sign * hat.astype(np.float32)
    partial = thin & (hat >= 0.4 * np.abs(top - ground))
    for _ in range(2):  # 8 px along a stroke from its pixels at the level
        found = partial & (cv2.dilate(found.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0) | found
    return found


def without_graphics(image: np.ndarray, graphics: np.ndarray) -> np.ndarray:
    """``image`` (float32) with the ``graphics`` pixels and their anti-aliased rim (two pixels
    around: a stroke's ends and corners are off its level) filled in from around them
    (OpenCV's Telea inpainting, 3 px): a ball or a wire a crosshair crosses keeps what shows of
    it beside the stroke."""
    rim = cv2.dilate(graphics.astype(np.uint8), np.ones((5, 5), np.uint8))
    out = np.array(image, dtype=np.float32, copy=True)
    # each cluster of strokes (a text block, the crosshair) inpainted in its own box, found on
    # a grid of 8 px cells: Telea's march over the whole frame cost 7 ms, the boxes a third
    H, W = out.shape
    ys, xs = np.nonzero(rim)
    cells = np.zeros(((H + 7) // 8, (W + 7) // 8), np.uint8)
    cells[ys // 8, xs // 8] = 1
    n, _, stats, _ = cv2.connectedComponentsWithStats(cv2.dilate(cells, np.ones((3, 3), np.uint8)))
    for x, y, w, h, _ in stats[1:n]:
        r0, r1 = max(8 * y - 4, 0), min(8 * (y + h) + 4, H)
        c0, c1 = max(8 * x - 4, 0), min(8 * (x + w) + 4, W)
        out[r0:r1, c0:c1] = cv2.inpaint(out[r0:r1, c0:c1].copy(), rim[r0:r1, c0:c1].copy(), 3, cv2.INPAINT_TELEA)
    return out


@dataclass(frozen=True)
class Cleaned:
    """What conditioning does to an image that neither polarity changes: its pixels (float32)
    with a display frame's clipped strokes and burned-in graphics filled in, and where it can
    be read at all. An image tried in both polarities, and by both detectors, is cleaned once."""

    pixels: np.ndarray
    #: True where the image holds information; None: everywhere
    valid: np.ndarray | None
    #: True where a pixel shows nothing of what lies there: clipped (:func:`fill_clipped`'s
    #: extremes) or burned-in graphics; None: nowhere
    hidden: np.ndarray | None = None
    #: the pixels at the frame's highest and at its lowest value (:func:`_at_extremes`), or None
    #: for a constant image
    extremes: tuple[np.ndarray, np.ndarray] | None = None


def cleaned(image: np.ndarray, display: bool, disc_px: int, levels: tuple[float, float] | None = None) -> Cleaned:
    """``image`` (H, W, pixels as stored) cleaned for either polarity: its invalid regions
    (:func:`invalid_regions`) and, for a ``display`` frame, its clipped strokes and burned-in
    graphics filled in (:func:`fill_clipped`, :func:`without_graphics`). ``disc_px`` and
    ``levels`` as for :func:`condition`."""
    bad = invalid_regions(image, disc_px, disc_px + 2, levels)
    high, low = _at_extremes(np.asarray(image), levels)
    filled = np.array(image, dtype=np.float32) if display else np.asarray(image, np.float32)
    if display and high is not None:
        filled = _filled(filled, high, low, FILL_RADIUS_PX, FILL_PASSES)
    graphics = burned_in_graphics(image, levels) if display else None
    if graphics is not None:
        filled = without_graphics(filled, graphics)
    hidden = None if high is None else high | low
    if graphics is not None:
        hidden = graphics if hidden is None else hidden | graphics
    return Cleaned(
        filled,
        None if bad is None else ~bad,
        hidden if hidden is not None and hidden.any() else None,
        None if high is None else (high, low),
    )


def condition(
    image: np.ndarray,
    polarity: str,
    formation: str | None,
    disc_px: int,
    levels: tuple[float, float] | None = None,
    clean: Cleaned | None = None,
) -> Conditioned:
    """The density image of ``image`` and its valid pixels (see the module).

    Parameters
    ----------
    image : (H, W) pixels as stored.
    polarity : "dense-dark" or "dense-bright".
    formation : "linear", "log", "display" or None (found by :func:`formation_of`).
    disc_px : the top-hat's disc radius, px: clipped regions narrower than it are kept, and
        the margin left out beside a clipped region is this wide.
    levels : the whole frame's (lowest, highest) pixel value when ``image`` is a crop of it
        (its clip levels); None: ``image``'s own.
    clean : ``image`` already cleaned (:func:`cleaned`, for this formation being a display
        frame or not, with these ``disc_px`` and ``levels``); None: cleaned here.

    Returns
    -------
    Conditioned
    """
    form = formation_of(image, polarity, formation)
    if clean is None:
        clean = cleaned(image, form == "display", disc_px, levels)
    censored = None
    if clean.extremes is not None:
        censored = clean.extremes[1] if polarity == "dense-dark" else clean.extremes[0]
    return Conditioned(
        to_density(clean.pixels, polarity, form),
        clean.valid,
        polarity,
        form,
        clean.hidden,
        censored if censored is not None and int(censored.sum()) >= MIN_CLIPPED_PX else None,
    )
