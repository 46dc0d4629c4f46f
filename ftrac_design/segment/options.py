"""Settings of the image path (:class:`TrackOptions`) and what it returns (:class:`TrackResult`).

:class:`TrackOptions` is the one flat record a user sets; each stage of the path takes only
the small frozen record of the settings it reads, built from it by a property —
:attr:`~TrackOptions.finding` (:class:`FindOptions`: detectors, sizes, thresholds),
:attr:`~TrackOptions.search` (:class:`SearchOptions`: polarities, regions, work budget),
:attr:`~TrackOptions.labelling` (:class:`LabellingOptions`, with its :class:`ContourOptions`
and :class:`NoiseOptions`: a labelling's solve, per-feature tests and misfit) and
:attr:`~TrackOptions.acceptance` (:class:`AcceptanceOptions`) — so every setting is decided
once, in :class:`TrackOptions`, and a stage's signature says what it reads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np

from ..pose import Diagnostics, NoiseModel, Observation, Pose, Status, TrackedPose, so3
from ..pose.record import failed_pose
from .beads import Beads
from .image import NoiseLevels
from .ridges import RidgePoints

#: how dense matter looks in an image: "auto" (the header, else the fiducial's own evidence),
#: "dense-dark" (raw detector counts) or "dense-bright" (log / display image)
Polarity = Literal["auto", "dense-dark", "dense-bright"]


@dataclass(frozen=True, eq=False)
class ViewPrior:
    """What is known of the view before the image is read: the fiducial's rotation F → X
    (SPEC §1) lies within ``within_rad`` of ``rotation`` — from an earlier image of the same
    set-up, or the C-arm's angles and how the fiducial is mounted.

    A small fiducial seen from ~600 mm is nearly in affine projection, where a labelling
    rotated 135–180° (a near-mirror) puts every ball and wire within a fraction of a pixel of
    where the right one does: the image alone cannot tell them apart, and the tracker refuses
    the tie. A prior that admits one of them decides it; one that admits the wrong one gives
    the wrong pose, confidently — the prior is the caller's word, not the image's.

    Attributes
    ----------
    rotation : (3, 3) the expected rotation F → X.
    within_rad : how far (rad, the angle of the rotation between them) the view's rotation
        may be from it; in (0, π].
    """

    rotation: np.ndarray
    within_rad: float

    def __post_init__(self) -> None:
        if not so3.is_rotation(self.rotation):
            raise ValueError("a view prior's rotation must be a proper 3 × 3 rotation matrix (orthonormal, det +1)")
        if not 0.0 < self.within_rad <= math.pi:
            raise ValueError(f"a view prior's angle must be in (0, π] rad, got {self.within_rad!r}")
        object.__setattr__(self, "rotation", np.asarray(self.rotation, float))

    def admits(self, R: np.ndarray, margin_rad: float = 0.0) -> np.ndarray:
        """Whether each rotation ``R`` ((3, 3) or (k, 3, 3)) lies within ``within_rad`` +
        ``margin_rad`` of :attr:`rotation` (bool, or (k,) bool)."""
        return so3.angle(np.asarray(R, float), self.rotation) <= self.within_rad + margin_rad


@dataclass(frozen=True)
class TrackOptions:
    """Settings of the image path; lengths in pixels unless named ``_mm``."""

    #: "auto", "dense-dark" (raw detector counts) or "dense-bright" (log/display image)
    polarity: Polarity = "auto"
    #: where the fiducial is, its polarity and its ball candidates: "learned" (the network of
    #: :mod:`ftrac_design.detector`, through ONNX Runtime), "classical" (blob detector and
    #: half-size search), or "auto" (learned when ONNX Runtime and the network are installed,
    #: then the classical detectors where the learned one finds no pose)
    detector: Literal["auto", "learned", "classical"] = "auto"
    #: threads ONNX Runtime may use for the learned detector, and with more than one the
    #: network runs beside the image's cleaning and noise map (its outputs are the same, bit
    #: for bit, with any number; two cut an image's time by a tenth to a quarter on the 2-core
    #: machine); 1 for a process among as many workers as cores (the image-true score's), where
    #: more threads only contend
    detector_threads: int = 2
    #: the learned detector's ball candidates kept from the whole image, most probable first:
    #: a frame of anatomy holds hundreds of ball-like peaks, and the fiducial's balls are
    #: looked for among those in its region
    detector_candidates: int = 256
    #: source-to-fiducial over source-to-detector distance assumed to size the filters
    #: (SPEC §1 workspace: the fiducial at 2/3 of f, magnification 1.5)
    magnification: float = 1.5
    #: the largest magnification a view may have (the fiducial at 1/3 of the way from the
    #: source): triplets of blobs farther apart than the balls can be are not labelled
    max_magnification: float = 3.0
    #: starting value of the Gaussian blur σ (fitted on the beads)
    blur_px: float = 0.8
    #: when the balls' fitted blur exceeds this multiple of ``blur_px`` (and 1.1 px), the
    #: image is detected again with the filters sized for the fitted blur
    blur_redetect: float = 1.4
    ridge_min_snr: float = 5.0
    bead_min_snr: float = 8.0
    #: first bead-matching tolerance (× the bead radius), then the refined one (px)
    hypothesis_tol_radii: float = 1.0
    #: how many balls a wire the image shows plainly (3 noise units) is worth when the bead
    #: hypotheses are ranked for refining: the image's ridges along a hypothesis' predicted
    #: wires (:func:`.evidence.ranking_support`) add this per noise unit to its matched count
    hypothesis_wire_weight: float = 0.5
    #: where no labelling of the first search over the learned detector's blob triplets gives
    #: a pose, or its answer shows fewer than half its wires (the wider search then challenges it), its
    #: triplets are followed by up to this many more, of the ``wide_blobs`` strongest blobs
    #: (0: no wider search). Among seeds, needles or dense anatomy the first search's 24 triplets of
    #: the 12 strongest blobs can all hold clutter, and a chance match of seven balls to
    #: clutter blobs then ends it (ftrac_2005 under brachytherapy seeds: all nine balls
    #: fitted, the strongest of them 3rd of 33 blobs, the right labelling never formed)
    wide_triplets: int = 48
    wide_blobs: int = 16
    #: where the answer shows fewer than half its wires, the wider search also tries up to this
    #: many triplets of the answer's own blobs, the largest triangles first (0: none). Seeds
    #: the learned detector ranks above the balls can stand in for a line's balls: ftrac_mini
    #: among seeds (fresh seed 2123) put its line of three on seeds 8.7 px from their own
    #: blobs, 17° off, and no triplet of the strongest blobs held three of the right six
    own_triplets: int = 84
    match_tol_px: float = 2.0
    #: contour points within this of a predicted curve belong to it (px); a second curve
    #: within ``separation_px`` makes a point ambiguous
    #: "guided": contour points measured where each labelling puts its wires
    #: (:mod:`~.guided`); "detected": the whole-image ridge points near the prediction
    contours: Literal["guided", "detected"] = "guided"
    #: a guided contour point needs a curvature across the wire of this many noise σ
    guided_min_snr: float = 3.0
    #: a wire too faint for that point by point is measured on runs of this many of its
    #: noise's correlation lengths (``thin_factor`` × the ridge scale) each, one point per
    #: run at √ this times the SNR (:func:`~.guided.guided_contours`); 0: not at all
    guided_pool: float = 3.0
    #: a run is a contour point at this many noise σ of its mean curvature across the wire;
    #: a line needs three such runs, an ellipse six
    guided_pool_min_snr: float = 2.0
    contour_tol_px: float = 2.0
    final_contour_tol_px: float = 1.0
    separation_px: float = 3.0
    #: contour points are thinned to one per ``thin_factor`` × the ridge scale of arc (the
    #: correlation length of Steger points' noise, ≈ 2√π σ for Gaussian-smoothed white noise)
    thin_factor: float = 3.5
    #: floors of the measured segmentation σ per axis (mm at the detector), from rendered
    #: images at the default imaging model (benchmarks/track_accuracy.py)
    floor_point_mm: float = 0.02
    #: systematic error per feature (px per axis / along the normal), see :func:`~.noise.measured_noise`
    sys_point_px: float = 0.07
    #: a ball's centre error per axis is its fit's own σ times ``point_fit_scale`` (the
    #: fit's pixels' noise is correlated: the σ it reports is too small), plus
    #: ``point_radius_scale`` × how far its fitted radius is from its fellows' median (px;
    #: a ball merged with a wire, a needle or a bone edge looks larger and its centre is
    #: pulled), plus ``point_size_scale`` × how far its apparent size √(r² / 5 + blur²) (px:
    #: the blurred ball's second moment per axis) is from the ``point_size_quantile`` of its
    #: fellows' (a ball on a display window's clipped shoulder, under a bone edge or on a
    #: tube's wall looks blurrier than the rest and its centre is off while its radius alone
    #: looks right; what disturbs a ball makes it look larger, so the reference is the
    #: sharper balls', not the median, which is itself a disturbed ball when half of them
    #: lie on a structure), and ``sys_point_px``; at most ``point_max_ratio`` × the
    #: labelling's median ball's, so that every ball counted still has to agree with the
    #: pose. The scales were fitted to the balls of right poses (seed 21, three presets, 12
    #: conditions) with the median as the size's reference; the lower third calibrates the
    #: same scales better on every preset (see :func:`~.noise.measured_noise`)
    point_fit_scale: float = 1.0
    point_radius_scale: float = 0.23
    point_size_scale: float = 0.81
    point_size_quantile: float = 1 / 3
    point_max_ratio: float = 3.0
    sys_curve_px: float = 0.04
    #: a curve type's contour scatter, measured about its own fits, is pooled with a prior of
    #: ``curve_prior_dof`` degrees of freedom at ``curve_prior_scale`` × the labelling's median
    #: ball fit σ: a conic through six points has one degree of freedom, and its scatter
    #: (0.05 px where the points lay 0.46 px RMS off the true ellipse) made a confident wrong
    #: pose. The scale is the median of the curves' scatter over their balls' σ (1.21–1.24 on
    #: ftrac_2005's lines and ellipses and ftrac_mini's ellipses, tuning seed 21); the prior's
    #: weight puts the short curves' errors on the long ones' scale (see :func:`~.noise.measured_noise`)
    curve_prior_dof: float = 4.0
    curve_prior_scale: float = 1.25
    floor_line_mm: float = 0.01
    floor_ellipse_mm: float = 0.01
    #: a feature whose own residual is this improbable under the noise model is dropped; a
    #: pose resting on balls alone whose whole χ² is this improbable is refused
    feature_p_value: float = 1e-6
    max_dropped: int = 2
    #: a second labelling whose misfit (χ² + charges, see :func:`~.labelling.misfit`) is within this of
    #: the best's, and that is far enough away, makes the answer ambiguous (one unexplained
    #: feature's charge: ftrac_mini's near-mirror labellings came within 24)
    ambiguity_chi2: float = 25.0
    #: ... within this of it for a labelling turned 90° or more from the best and no farther
    #: than the fiducial's extent, in a view that perspective does not set apart from its
    #: mirror image (:func:`~.region.mirror_distinct`):
    #: there a near-mirror labelling puts every feature within a fraction of a pixel of the
    #: right one's, and what separates their misfits is which blobs each used and how those
    #: fitted, not what the image shows (a ftrac_mini near-mirror 176° off fitted 3 balls and
    #: both ellipses 26.6 better than the right labelling's 4 balls and both ellipses, held-out
    #: seed 2126; the image's pixels preferred the right one by 16.6 units)
    mirror_ambiguity_chi2: float = 50.0
    #: ... unless it lies inside the best pose's own covariance (its difference's χ²₆ at
    #: most this, p = 0.99): given out, the pose already says it may be there
    rival_inside_chi2: float = 16.8
    #: ... unless the image's pixels prefer the best by this many units
    #: (:func:`~.acceptance.settled_by_pixels`); 0 turns the pixels' word off
    pixel_tie_z: float = 3.0
    #: a predicted wire whose median ridge evidence (:func:`~.evidence.curve_support`, noise
    #: units) is below ``wire_min_snr``, or below ``wire_support`` × the median predicted
    #: wire's, is absent: the labelling is not confirmed
    wire_support: float = 0.2
    wire_min_snr: float = 1.5
    #: predicted wire whose ridge evidence is below this counts as unsupported in the
    #: labelling's agreement with the image (:func:`~.evidence.image_agreement`)
    agreement_min_snr: float = 1.5
    #: χ² charged for each predicted, unobstructed feature a labelling does not explain
    unexplained_chi2: float = 25.0
    #: look for the fiducial on a half-size image first and work in its regions only
    roi: bool = True
    #: how many regions where the fiducial may be are searched, most likely first
    max_regions: int = 3
    #: the regions are looked for on a half-size image when a ball's radius there is at
    #: least this (px), else at full size
    min_region_bead_px: float = 1.2
    #: when no region gives a pose, the whole image is searched only if it has at most
    #: this many pixels (a 1024² search cost ~0.3 s and found what the regions had not in
    #: too few images to pay for it)
    whole_image_px: int = 512 * 512
    #: the work one image may cost, counted: each search of a region or a whole image (for
    #: each polarity tried) and each labelling refined is one unit; once spent, no further
    #: polarity, region or labelling is tried and the answer so far is given. The answer
    #: depends on this count, never on the machine's speed
    max_work: int = 24
    #: how many of the best bead hypotheses are refined into labellings (one unit of work
    #: each)
    labellings: int = 4
    #: how many, for a wire design, when the best labelling refined so far gives a pose
    #: that rests on little (two or more of the design's balls unexplained, or fewer than
    #: half its wires): a near-mirror labelling of ftrac_2005 over strong anatomy (5 balls
    #: and both ellipses, no line readable) passed 166° off while the right one, ranked
    #: sixth, was never refined
    labellings_if_weak: int = 8
    #: wall-clock seconds after which no further search or labelling starts (the one under
    #: way finishes): a safety net for an image whose counted work runs far longer than any
    #: benchmark image's, not the bound that decides an ordinary image's answer. Each
    #: detector's pass has its own. At 4 s it stopped passes of 2–4 s on the 2-core machine
    #: whenever other work loaded it, and one image's answer changed with the load; with no
    #: net the slowest of 780 realism images took 5.3 s there, both passes together
    time_budget_s: float = 30.0
    #: χ² charged per pixel of ridge the pose leaves unexplained and of predicted wire the
    #: image does not show (:func:`~.evidence.image_agreement`)
    agreement_chi2_per_px: float = 1.0
    #: two refinement stages (wide, then tight and thinned) instead of three
    fast: bool = True
    #: a converged pose may leave at most this many balls in view, clear of the others (their
    #: blurred discs touch none: > 2 radii + 2 blur σ), without their blob or rejected — a
    #: group of touching balls the image shows at none of them counting as one such ball
    max_unexplained_beads: int = 1
    #: a ball the labelling did not use is still shown by the image where the blob
    #: detector reads at least this many noise units at its predicted centre
    bead_present_snr: float = 4.0
    #: a group of touching balls is shown at none of them only where the blob detector reads
    #: less than this at each (noise units), and the network no ball: blended, a faint pair's
    #: response splits between them (a right ftrac_mini pose on a display frame: 3.4 and 4.0),
    #: while balls put on bare background read what the noise gives (−1.3 and −5.3)
    bare_group_snr: float = 2.0
    #: a confident labelling uses at least this many balls
    min_beads: int = 5
    #: one ball fewer will do where wire contours confirm the labelling and the view's
    #: perspective tells it from its mirror (:func:`~.region.balls_needed`): the fiducial
    #: reflected through the plane square to the line of sight through its centre, aligned on
    #: the view by the best affine map, puts a ball, wire end or ellipse point at least this
    #: far (px) from where the view puts it — beyond the 2 px within which balls are matched.
    #: The near-mirror labellings that ``min_beads`` guards against (ftrac_mini, 3–4 balls and
    #: both ellipses, 168–173° off) fit the wires because that reflection moves nothing of
    #: the 1 × 1 × 2 cm presets by more than 0.26–0.42 px over SPEC §1's workspace; ftrac_2005's views are 2.3–3.1 px
    #: from theirs (1,000 workspace poses each); 0 never lowers ``min_beads``. The same
    #: distance decides where bead hypotheses are ranked with their wires read at the pose
    #: fitted to all their balls (:func:`~.pipeline.ranked_hypotheses`; 0: nowhere)
    mirror_signal_px: float = 2.0
    #: where the balls a labelling leaves out because their blobs blend with its others' (and
    #: which the image shows where it puts them) make up the balls it needs, in a view not set
    #: apart from its mirror image, the features it did fit must fit as well as features do:
    #: their χ² (the variance factor × its degrees of freedom) at least this probable. A
    #: near-mirror labelling of ftrac_mini passed so at p = 9·10⁻⁷ and another met it as a
    #: rival at 5·10⁻⁶ (held-out seed 2124); the right ones it held up were at p ≥ 3·10⁻³ there
    crowd_p_value: float = 1e-5
    #: a wire design's labelling of six balls or more whose wires gave no contour from the first
    #: stands on fewer balls than all but one where, in a view set apart from its mirror
    #: image, the image's ridges show its ellipses and all its curves but one and the features
    #: it did fit fit as features do: their χ² at least this probable
    #: (:func:`~.acceptance.ridges_confirm`); 0 takes that confirmation whatever the fit, 1 never
    ridge_confirm_p_value: float = 1e-5
    #: a blob whose blurred-sphere fit leaves a residual RMS above ``ball_shape_rms`` noise σ
    #: and above ``ball_shape_fraction`` of its own peak contrast is not shaped like a ball
    #: (:func:`~.acceptance.misshapen_balls`); a confident labelling uses at most
    #: ``max_misshapen_balls`` such blobs as balls
    ball_shape_rms: float = 3.0
    ball_shape_fraction: float = 0.1
    max_misshapen_balls: int = 2
    #: a confident labelling's balls look at least this fraction as large as balls of the
    #: design's diameters can at its pose's depths (median second moments against the median
    #: of their projected chords' alone, r²/5: :func:`~.acceptance.small_balls`)
    ball_size_fraction: float = 0.85
    #: a blob among the fiducial's balls (inside their projected hull, more than two radii from
    #: every ball the pose puts there, not where two of its wires cross) with a blob response at
    #: least ``stray_ball_fraction`` of the median of the balls the labelling uses is a ball the
    #: pose does not explain; a confident labelling leaves at most ``max_stray_balls`` of them
    #: (:func:`~.acceptance.stray_balls`)
    stray_ball_fraction: float = 0.7
    max_stray_balls: int = 3
    #: a pose whose every wire the image's ridges alone show plainly and that uses at least
    #: this share of the design's balls is not refused for such blobs (all its balls with one
    #: straight wire faint): its fiducial is there, the blobs another object's
    plain_wires_ball_share: float = 2 / 3
    #: a ball the pose does not use, clear of the others, whose blob (a response at least
    #: ``stray_ball_fraction`` of the used balls' median) the image shows more than
    #: ``displaced_ball_px`` and less than two radii + 1 px from where the pose puts it, and
    #: no other ball there, is displaced, and so is a ball-like blob the pose leaves more than
    #: ``displaced_ball_px`` from every ball but near enough that their discs touch; a confident
    #: labelling leaves at most ``max_displaced_balls`` such balls (:func:`~.acceptance.displaced_balls`)
    displaced_ball_px: float = 2.0
    max_displaced_balls: int = 1
    #: redundant constraints (2 per bead and line, 5 per ellipse, minus 6) a confident
    #: labelling needs
    min_redundancy: int = 6
    #: every feature's error must show in its own residual: the smallest redundancy number
    #: (1 − the whitened hat matrix's diagonal, per row) a feature of a confident pose may have
    #: (:func:`~.acceptance.uncontrolled`); 0 turns the test off
    min_feature_redundancy: float = 0.05
    #: the solver's maximum noise scale κ for an image pose (the model is measured here)
    max_noise_scale: float = 3.0
    #: variance components qₖ of the pose covariance per feature type, relative to the
    #: residuals' variance factor (see :func:`~.noise.calibrated_covariance`); chosen against the
    #: truth on rendered images (600 ftrac_2005, 180 ftrac_mini, 200 nine_bead; clean and
    #: over anatomy): the error over its σ had an RMS of 0.55–1.2 on every axis, before the
    #: Student-t factor ν/(ν − 2) widened each σ by 3–18 % (ν = 40 … 7 residual dof; 9 % at 12)
    variance_point: float = 2.0
    variance_line: float = 2.0
    variance_ellipse: float = 1.0
    #: a labelling's pose must put the fiducial's origin between these fractions of the
    #: source-to-detector distance (magnification 1.01–10): the fiducial lies between the
    #: source and the detector, and a pose outside is a wrong labelling (its body rendered
    #: over 10⁸ pixels before this test)
    depth_range: tuple[float, float] = (0.1, 0.99)
    #: σ (mm at 100 mm from the principal point) of an image distortion nobody corrected —
    #: an image intensifier's pincushion, S-distortion and the pincushion's off-centre terms,
    #: up to ~2 mm there (Jain et al. 2005) — added to the pose covariance
    #: (:func:`~.noise.distortion_covariance`): a
    #: pinhole pose from such an image is biased in depth by several mm and no residual
    #: shows it. 0 for a flat-panel detector or an image corrected with its distortion model.
    distortion_prior_mm: float = 1.5
    #: σ (px) of an offset shared by the ellipse contours along their normals, added to the
    #: pose covariance (:func:`~.noise.contour_offset_covariance`) for a design with a body:
    #: the body's subtracted projection leaves a little of its limb's slope under the wires.
    #: On 20 clean ftrac_2005 frames of tuning seed 21 their points lay 0.008 and 0.011 px
    #: inside the true ellipses on average (0.0015 and 0.0006 px with no body drawn or
    #: subtracted) and the poses 0.10 mm too far — twice what a 0.01 px offset moves the
    #: least-squares pose, whose balls and lines hold it back; at 0.02 px the depth's error
    #: over its σ spread 1.18 there (2.16 without the term). 0 turns the term off
    contour_offset_px: float = 0.02
    #: the view as known before the image is read (:class:`ViewPrior`): only labellings whose
    #: rotation it admits are searched for and given out; None: any view
    view: ViewPrior | None = None

    @property
    def finding(self) -> FindOptions:
        """What finding the features reads (:class:`FindOptions`)."""
        return _taken(FindOptions, self)

    @property
    def search(self) -> SearchOptions:
        """What the search over polarities and regions reads (:class:`SearchOptions`)."""
        return _taken(SearchOptions, self)

    @property
    def labelling(self) -> LabellingOptions:
        """What a labelling's solve, per-feature tests and misfit read (:class:`LabellingOptions`)."""
        return _taken(LabellingOptions, self, contour=_taken(ContourOptions, self), noise=_taken(NoiseOptions, self))

    @property
    def acceptance(self) -> AcceptanceOptions:
        """What the acceptance tests read (:class:`AcceptanceOptions`)."""
        return _taken(AcceptanceOptions, self)


# The stages' records: each field is :class:`TrackOptions`' of the same name (its meaning and
# units are given there), and none has a default, so that a setting is decided only there.


@dataclass(frozen=True)
class FindOptions:
    """What finding the features reads: the detector, the expected sizes (magnification and
    blur, px), the balls' and ridges' SNR thresholds and the bead hypotheses' tolerance."""

    detector: Literal["auto", "learned", "classical"]
    detector_threads: int
    detector_candidates: int
    magnification: float
    max_magnification: float
    blur_px: float
    blur_redetect: float
    ridge_min_snr: float
    bead_min_snr: float
    hypothesis_tol_radii: float
    hypothesis_wire_weight: float
    wide_triplets: int
    wide_blobs: int
    own_triplets: int
    view: ViewPrior | None


@dataclass(frozen=True)
class SearchOptions:
    """What the search reads: the polarities tried, the regions searched (a ball's radius in
    px, an image's size in pixels) and the work one image may cost (units, seconds)."""

    polarity: Polarity
    roi: bool
    max_regions: int
    min_region_bead_px: float
    whole_image_px: int
    max_work: int
    labellings: int
    labellings_if_weak: int
    time_budget_s: float


@dataclass(frozen=True)
class ContourOptions:
    """What gathering a labelling's contour points reads: how (guided or detected), the
    tolerances and spacing (px) and the magnification assumed for a pose without depth."""

    magnification: float
    contours: Literal["guided", "detected"]
    guided_min_snr: float
    guided_pool: float
    guided_pool_min_snr: float
    contour_tol_px: float
    final_contour_tol_px: float
    separation_px: float
    thin_factor: float


@dataclass(frozen=True)
class NoiseOptions:
    """What the measured noise model and the pose covariance read: floors (mm at the
    detector), systematic errors (px), variance components and the distortion prior (mm)."""

    floor_point_mm: float
    sys_point_px: float
    point_fit_scale: float
    point_radius_scale: float
    point_size_scale: float
    point_size_quantile: float
    point_max_ratio: float
    sys_curve_px: float
    curve_prior_dof: float
    curve_prior_scale: float
    floor_line_mm: float
    floor_ellipse_mm: float
    variance_point: float
    variance_line: float
    variance_ellipse: float
    distortion_prior_mm: float
    contour_offset_px: float


@dataclass(frozen=True)
class LabellingOptions:
    """What a labelling's staged solve, its per-feature tests and its misfit read: bead
    matching tolerance (px), stages, the solver's noise scale, dropping, plausible depth,
    the misfit's charges (χ²), and its contours' and noise model's records."""

    match_tol_px: float
    fast: bool
    max_noise_scale: float
    feature_p_value: float
    max_dropped: int
    depth_range: tuple[float, float]
    unexplained_chi2: float
    bead_present_snr: float
    bare_group_snr: float
    agreement_min_snr: float
    agreement_chi2_per_px: float
    contour: ContourOptions
    noise: NoiseOptions


@dataclass(frozen=True)
class AcceptanceOptions:
    """What the acceptance tests read: the rival labelling's misfit margin (χ²), the wires'
    evidence (noise units, fraction) and the evidence a confident labelling needs (counts, and
    each feature's smallest redundancy number)."""

    ambiguity_chi2: float
    mirror_ambiguity_chi2: float
    rival_inside_chi2: float
    pixel_tie_z: float
    wire_support: float
    wire_min_snr: float
    max_unexplained_beads: int
    min_beads: int
    mirror_signal_px: float
    crowd_p_value: float
    ridge_confirm_p_value: float
    ball_shape_rms: float
    ball_shape_fraction: float
    max_misshapen_balls: int
    ball_size_fraction: float
    stray_ball_fraction: float
    max_stray_balls: int
    plain_wires_ball_share: float
    displaced_ball_px: float
    max_displaced_balls: int
    min_redundancy: int
    min_feature_redundancy: float
    feature_p_value: float


def _taken(record: type, opts: TrackOptions, **given: Any) -> Any:
    """``record`` with each field not in ``given`` taken from ``opts``' field of that name."""
    return record(**{f.name: getattr(opts, f.name) for f in fields(record) if f.name not in given}, **given)


@dataclass
class TrackResult:
    """What :func:`~ftrac_design.segment.track_image` found: the pose (SPEC §4, converged or
    not, with the reason), the observation it segmented (SPEC §3), per-feature quality, the
    raw detections (for the overlay) and what the path saw (:class:`~ftrac_design.pose.Diagnostics`)."""

    pose: Pose
    observation: Observation | None
    quality: dict[str, Any]
    beads: Beads | None
    ridges: RidgePoints | None
    polarity: str
    noise: NoiseModel | None
    diagnostics: Diagnostics = field(default_factory=Diagnostics)
    #: the image's noise level function at the ridge scale the pose was found with (not
    #: written out; a run tracker reuses it for the run's next frames)
    noise_levels: NoiseLevels | None = field(default=None, repr=False, compare=False)

    def record(self, status: Status | None = None) -> TrackedPose:
        """The pose as it is written (:class:`~ftrac_design.pose.TrackedPose`): the SPEC §4 pose
        with the ``segmentation`` diagnostics (polarity, measured noise model, what the path saw)
        and ``status`` (a frame's, or None)."""
        diag = replace(self.diagnostics, polarity=self.polarity, noise_model_mm=self.noise)
        return TrackedPose(self.pose, status, diag)

    def observation_dict(self) -> dict[str, Any] | None:
        """SPEC §3 object plus ``quality`` (per feature; readers ignore unknown keys)."""
        if self.observation is None:
            return None
        d = self.observation.to_dict()
        d["quality"] = self.quality
        return d


def failed_result(
    reason: str,
    polarity: str = "",
    beads: Beads | None = None,
    ridges: RidgePoints | None = None,
    diagnostics: Diagnostics | None = None,
) -> TrackResult:
    """A :class:`TrackResult` without a pose: nothing was identified, for ``reason``."""
    return TrackResult(failed_pose(reason), None, {}, beads, ridges, polarity, None, diagnostics or Diagnostics())
