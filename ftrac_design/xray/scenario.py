"""Hard, realistic test images of a fiducial at a pose: a patient behind it and a C-arm's image chain.

:func:`realistic_image` makes one image for a named condition, every setting drawn from
``seed`` within the ranges below (what real C-arms and patients span), so that a benchmark of a
few hundred images per condition covers the field. The fiducial is rendered by
:func:`.render.detected_deficit` (its photons times the patient's, through its focal-spot
blur, the detector's line spread and the pixels), the patient by :func:`.patient.patient`
(its own focal blur, then the detector's line spread), and
:func:`.display.apply_chain` adds the noise once and forms the stored image.

Common to all conditions (per seed): the patient (:data:`KIND_WEIGHTS`, placement, build,
thickness 150–300 mm), the patient plane's magnification ``f / (t_z + U(−40, 60) mm)``, the
effective energy from the patient's thickness (automatic exposure control raises the kV:
50 keV at 150 mm to 70 keV at 350 mm), focal spot 0.3–1.2 mm, detector line spread σ
0.5–0.9 px, scatter-to-primary 0.2–1.2, flat-field residual 0–1 %, 14/16-bit flat panel or
12-bit image intensifier (vignetting 0.1–0.35, post-sink blur 0–0.6 px), gain putting the
brightest patient pixels of the central field at 40–80 % of full scale (the direct beam
beside the patient saturates), dark offset, read noise 0–4 quanta.

==================  ==========================================================================
condition           what it stresses
==================  ==========================================================================
raw                 linear 14/16-bit counts (dense = dark), radiograph dose 1000–5000 quanta
                    behind the patient, the direct beam saturated
log                 float32 line integral (dense = bright), radiograph dose
display-dark        8-bit display frame, dense = dark (fluoroscopy monitor), dose 200–3000,
                    window auto from the 0–2 / 98–100 % percentiles (one in three 2–8 / 92–98 %),
                    gamma 0.6–1.6, unsharp mask σ 2–12 px × 0–1.5, burned-in text half the time
display-bright      the same, dense = bright (radiograph look)
round-shutter       image intensifier: round field, black outside, radius 35–50 % of the image
                    (larger if the fiducial needs it), vignetting; display frame either polarity
blades              2–4 collimator blades, 2–8 % transmission, penumbra σ 1–4 px, turned up to
                    ±30°, 15–60 px from the fiducial; linear or display
fluoro-dose         100–500 quanta behind the patient; display frame either polarity
strong-anatomy      pelvis or spine with a dense landmark (femoral head, acetabulum, sacrum,
                    vertebral body, pubis, ...) right behind the fiducial, thick patient; log
                    or display
blur-2px            total blur σ 1.6–2.0 px at the fiducial; display or log
seeds-needle        30–100 titanium seeds, 0–3 clips and 1–2 steel needles (Ø 1.27 mm) across
                    the fiducial; linear or display
==================  ==========================================================================

The fiducial stays inside the exposed field for every condition.
"""

from __future__ import annotations

import math
from dataclasses import asdict, replace
from typing import Any, Literal, get_args

import cv2
import numpy as np

from ..errors import InputError
from ..features.model import Features
from ..pose.camera import Camera
from .display import Detector, Display, Shutter, apply_chain, n0_for_counts
from .model import ImagingModel, Occluder
from .patient import (
    PatientModel,
    clips,
    over_body,
    patient_model,
    place_at,
    render_patient,
    seeds,
    structure_center,
    texture,
)
from .render import blur_sigma_px, detected_deficit, detector_box, transmission_box, window

Condition = Literal[
    "raw",
    "log",
    "display-dark",
    "display-bright",
    "round-shutter",
    "blades",
    "fluoro-dose",
    "strong-anatomy",
    "blur-2px",
    "seeds-needle",
]
#: every condition, in the order of :data:`Condition`
CONDITIONS: tuple[str, ...] = get_args(Condition)
#: how often each kind of patient view is drawn (strong-anatomy: pelvis and spine only)
KIND_WEIGHTS = {"pelvis": 0.4, "spine": 0.2, "abdomen": 0.2, "chest": 0.2}
#: structures put right behind the fiducial for strong-anatomy, by the kind of view
DENSE = {
    "pelvis": (
        "femoral head",
        "acetabulum",
        "sacrum",
        "pubic body",
        "femoral neck",
        "greater trochanter",
        "iliac crest",
        "iliac wing",
        "ischium",
        "superior pubic ramus",
        "L5 body",
        "L4 body",
    ),
    "spine": tuple(
        f"{v} {part}"
        for v in ("T11", "T12", "L1", "L2", "L3", "L4", "L5")
        for part in ("body", "pedicle", "spinous process", "transverse process")
    ),
}


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _footprint(features: Features, R, t, camera: Camera, imaging: ImagingModel):
    """The fiducial's transmission box (focal blur only), its origin (row, col) and its
    footprint (u0, v0, u1, v1) px: the pixels it attenuates by more than 0.1 %."""
    Ib, (r0, c0) = transmission_box(features, R, t, camera, imaging, ())
    if Ib.size == 0:
        raise InputError(None, "pose", "a pose that puts the fiducial inside the image")
    jj, ii = np.nonzero(Ib < 0.999)
    if len(jj) == 0:
        jj, ii = np.array([0, Ib.shape[0] - 1]), np.array([0, Ib.shape[1] - 1])
    return Ib, (r0, c0), (c0 + int(ii.min()), r0 + int(jj.min()), c0 + int(ii.max()), r0 + int(jj.max()))


def _strong_placement(model: PatientModel, rng, fid_uv, shape, pixel_mm, mag) -> tuple[PatientModel, str]:
    names = DENSE[model.kind]
    cand = [st for st in model.structures if st.name in names]
    st = cand[int(rng.integers(len(cand)))]
    x, y = structure_center(st)
    jitter = rng.normal(0, 4.0, 2)  # mm: not always dead centre
    return place_at(model, (x + jitter[0], y + jitter[1]), fid_uv, shape, pixel_mm, mag), st.name


def _shutter(condition: str, rng, box, shape) -> Shutter:
    H, W = shape
    u0, v0, u1, v1 = box
    if condition == "round-shutter":
        c = ((W - 1) / 2 + rng.normal(0, 15), (H - 1) / 2 + rng.normal(0, 15))
        corners = np.array([[u0, v0], [u1, v0], [u0, v1], [u1, v1]], float)
        need = float(np.max(np.hypot(corners[:, 0] - c[0], corners[:, 1] - c[1]))) + rng.uniform(10, 40)
        r = max(float(rng.uniform(0.35, 0.5)) * min(H, W), need)
        return Shutter("round", c, r, float(rng.uniform(1.0, 2.0)))
    if condition == "blades":
        angle = 0.0 if rng.random() < 0.3 else float(rng.uniform(-0.5, 0.5))
        c = ((u0 + u1) / 2, (v0 + v1) / 2)
        ca, sa = math.cos(angle), math.sin(angle)
        corners = np.array([[u0, v0], [u1, v0], [u0, v1], [u1, v1]], float) - c
        x = corners[:, 0] * ca + corners[:, 1] * sa
        y = -corners[:, 0] * sa + corners[:, 1] * ca
        margins = rng.uniform(15, 60, 4)
        opening = [-x.min() + margins[0], x.max() + margins[1], -y.min() + margins[2], y.max() + margins[3]]
        n_blades = int(rng.integers(2, 5))
        for k in rng.choice(4, 4 - n_blades, replace=False):
            opening[k] = math.inf
        return Shutter(
            "blades",
            c,
            opening_px=tuple(opening),
            angle=angle,
            transmission=float(rng.uniform(0.02, 0.08)),
            penumbra_px=float(rng.uniform(1.0, 4.0)),
        )
    return Shutter()


def _display(condition: str, rng, box) -> Display:
    formation = {"raw": "linear", "log": "log"}.get(condition)
    if formation is None:
        choices = {
            "blades": ("linear", "display"),
            "seeds-needle": ("linear", "display"),
            "strong-anatomy": ("log", "display", "display"),
            "blur-2px": ("log", "display", "display"),
        }
        formation = str(rng.choice(choices.get(condition, ("display",))))
    if formation != "display":
        return Display(formation)
    polarity = {"display-dark": "dense-dark", "display-bright": "dense-bright"}.get(
        condition, "dense-dark" if rng.random() < 0.5 else "dense-bright"
    )
    # the automatic window, or one time in three a tighter one (a user's contrast boost)
    if rng.random() < 1 / 3:
        pct = (float(rng.uniform(2.0, 8.0)), float(rng.uniform(92.0, 98.0)))
    else:
        pct = (float(rng.uniform(0.0, 2.0)), float(rng.uniform(98.0, 100.0)))
    return Display(
        "display",
        None,
        pct,
        _loguniform(rng, 0.6, 1.6),
        float(rng.uniform(2.0, 12.0)),
        float(rng.uniform(0.0, 1.5)) if rng.random() < 0.8 else 0.0,
        polarity,
        8,
        bool(rng.random() < 0.5),
        float(rng.uniform(0.0, 1.5)),
    )


def _needles(features: Features, rng, n: int) -> tuple[Occluder, ...]:
    """Steel needles (18 G, Ø 1.27 mm) across the fiducial's middle, in F."""
    c0 = features.point_centers().mean(0) if features.points else np.zeros(3)
    out = []
    for _ in range(n):
        c = c0 + rng.uniform(-8, 8, 3)
        a = rng.uniform(0, 2 * np.pi)
        d = np.array([math.cos(a), math.sin(a), rng.uniform(-0.6, 0.6)])
        d /= np.linalg.norm(d)
        out.append(Occluder(tuple(c - 80 * d), tuple(c + 80 * d)))
    return tuple(out)


def _detector(rng, expected: np.ndarray, intensifier: bool) -> Detector:
    """A flat panel (14/16 bits) or an image intensifier (12 bits): the brightest patient pixels
    of the central measuring field (99.5th percentile of the expected quanta, scatter
    included) at 40–80 % of full scale, so the fiducial's neighbourhood stays in range while
    the direct beam beside the patient saturates."""
    bits = 12 if intensifier else int(rng.choice([14, 16]))
    full = (1 << bits) - 1
    spr = float(rng.uniform(0.2, 1.2))
    H, W = expected.shape
    central = expected[H // 4 : H - H // 4 : 4, W // 4 : W - W // 4 : 4]
    bright = float(np.percentile(central, 99.5)) + spr * float(central.mean())
    gain = float(rng.uniform(0.4, 0.8)) * full / max(bright, 1e-6)
    return Detector(
        bits,
        gain,
        float(rng.uniform(0.0, 0.02)) * full,
        float(rng.uniform(0.0, 4.0)) * gain,
        float(rng.uniform(0.0, 0.01)),
        spr,
        float(rng.uniform(40, 120)),
        float(rng.uniform(0.1, 0.35)) if intensifier else 0.0,
        float(rng.uniform(0.0, 0.6)) if intensifier else 0.0,
    )


def _dose(condition: str, rng) -> float:
    if condition == "fluoro-dose":
        return float(rng.uniform(100, 500))
    if condition in ("raw", "log", "strong-anatomy", "seeds-needle", "blades"):
        return _loguniform(rng, 1000, 5000)
    return _loguniform(rng, 200, 3000)


def _blurs(
    condition: str, rng: np.random.Generator, camera: Camera, shape: tuple[int, int], depth_mm: float
) -> tuple[float, ImagingModel, float, float]:
    """The focal spot drawn (mm), the imaging model of the fiducial blurred by that spot alone
    (the detector's line spread comes later), the focal blur σ at ``depth_mm`` and the detector's
    σ that makes up the total drawn for ``condition`` (px)."""
    focal = float(rng.uniform(0.3, 0.7) if condition == "fluoro-dose" else rng.uniform(0.3, 1.2))
    imaging = ImagingModel(image_shape=shape, focal_spot_mm=focal, detector_blur_px=0.0, photons_per_px=None)
    su, sv = blur_sigma_px(camera, imaging, depth_mm)
    sigma_focal = math.hypot(su, sv) / math.sqrt(2)
    sigma_target = float(rng.uniform(1.6, 2.0)) if condition == "blur-2px" else float(rng.uniform(0.5, 0.9))
    return focal, imaging, sigma_focal, math.sqrt(max(sigma_target**2 - sigma_focal**2, 0.0))


def realistic_image(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera = Camera(),
    condition: Condition = "raw",
    seed: int = 0,
    shape: tuple[int, int] | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """A test image of ``features`` at pose (R, t) (F → X, mm) under ``condition`` (see the module).

    Parameters
    ----------
    features, R, t, camera : the fiducial (its body ``features.body`` rendered too, where known),
        its pose and the C-arm's intrinsics (SPEC §1).
    condition : one of :data:`CONDITIONS`.
    seed : draws every setting, the patient and the noise; the same seed gives the same image.
    shape : image (rows, columns); default twice the principal point.

    Returns
    -------
    (image, info): the stored image (uint16 linear, float32 log, uint8 display) and a dict
    with ``condition``, ``seed``, ``formation``, ``polarity``, ``field_mask`` (bool (H, W),
    True = exposed), ``counts_behind_patient``, ``n0``, ``fiducial_box`` (u0, v0, u1, v1),
    ``blur_sigma_px`` (total at the fiducial), ``energy_kev``, ``focal_spot_mm``,
    ``patient`` (kind, thickness, placement, landmark, line-integral range), ``detector``,
    ``display``, ``shutter``, the implants and everything else drawn.
    """
    if condition not in CONDITIONS:
        raise InputError(None, "condition", f"one of {', '.join(CONDITIONS)}, got {condition!r}")
    if shape is None:
        shape = (int(round(2 * camera.principal_point_px[1])), int(round(2 * camera.principal_point_px[0])))
    H, W = int(shape[0]), int(shape[1])
    R, t = np.asarray(R, float), np.asarray(t, float)
    rng = np.random.default_rng([int(seed), CONDITIONS.index(condition), 2024])
    pixel = float(np.mean(camera.pixel_size_mm))
    focal, imaging, sigma_focal, sigma_det = _blurs(condition, rng, camera, (H, W), float(t[2]))
    occluders = _needles(features, rng, int(rng.integers(1, 3))) if condition == "seeds-needle" else ()
    _, _, box = _footprint(features, R, t, camera, imaging)

    mag = camera.focal_length_mm / (float(t[2]) + float(rng.uniform(-40, 60)))
    bg, patient_info = _patient(condition, rng, box, (H, W), pixel, mag)

    T = _photons(features, R, t, camera, imaging, occluders, bg, mag, focal, sigma_det)
    counts = _dose(condition, rng)
    n0 = n0_for_counts(bg, counts)
    intensifier = condition == "round-shutter" or (
        condition in ("display-dark", "display-bright", "fluoro-dose", "blur-2px") and rng.random() < 0.5
    )
    expected = np.float32(n0) * T
    detector = _detector(rng, expected, intensifier)
    shutter = _shutter(condition, rng, box, (H, W))
    display = _display(condition, rng, box)
    image, info = apply_chain(expected, detector, display, shutter, rng, n0=n0)
    info.update(
        {
            "condition": condition,
            "seed": int(seed),
            "counts_behind_patient": counts,
            "fiducial_box": box,
            "blur_sigma_px": math.hypot(sigma_focal, sigma_det),
            "detector_blur_px": sigma_det,
            "focal_spot_mm": focal,
            "energy_kev": patient_info.pop("energy_kev"),
            "intensifier": intensifier,
            "patient": patient_info,
            "seeds": patient_info.pop("seeds"),
            "clips": patient_info.pop("clips"),
            "needles": [oc.to_dict() for oc in occluders],
            "detector": asdict(detector),
            "display": asdict(display),
            "shutter_settings": asdict(shutter),
        }
    )
    return image, info


def _photons(
    features: Features,
    R,
    t,
    camera: Camera,
    imaging: ImagingModel,
    occluders,
    bg: np.ndarray,
    mag: float,
    focal: float,
    sigma_det: float,
) -> np.ndarray:
    """I/I0 (H, W) as the detector reads it: the patient's transmission (its own focal blur)
    times the fiducial's on the photon field, through the fiducial's focal blur, the
    detector's line spread and the pixels (:func:`.render.detected_deficit`). The patient's
    transmission is taken as constant over a pixel and over the fiducial's focal blur
    (σ ≤ 0.6 px at the largest spot)."""
    pixel = float(np.mean(camera.pixel_size_mm))
    patient_focal = max(mag - 1.0, 0.0) * focal / 2.3548 / pixel
    Tp = np.exp(-bg)
    if patient_focal > 0.05:
        Tp = cv2.GaussianBlur(Tp, (0, 0), patient_focal, borderType=cv2.BORDER_REFLECT)
    T = cv2.GaussianBlur(Tp, (0, 0), sigma_det, borderType=cv2.BORDER_REFLECT) if sigma_det > 0 else Tp.copy()
    total = replace(imaging, detector_blur_px=sigma_det)
    field, (r0, c0) = detector_box(features, R, t, camera, total, occluders)
    if field is not None:
        v0, u0 = field.origin
        h, w = field.p.shape
        su, sv = blur_sigma_px(camera, total, float(t[2]))
        D = detected_deficit(field, su, sv, window(Tp, (v0, u0), (h, w)))
        H, W = T.shape
        D = D[r0 - v0 : min(v0 + h, H) - v0, c0 - u0 : min(u0 + w, W) - u0]
        # the patient detected on its own (pixel grid) and the fiducial's deficit detected
        # with it on the photon field are two discretisations: where the patient changes
        # sharply under a dense part the difference can dip below zero photons
        T[r0 : r0 + D.shape[0], c0 : c0 + D.shape[1]] -= D
        np.maximum(T, 0.0, out=T)
    return T


def _patient(condition: str, rng, box, shape, pixel: float, mag: float) -> tuple[np.ndarray, dict[str, Any]]:
    """The patient's line integral (with seeds and clips for seeds-needle) behind the fiducial's
    footprint ``box``, and what was drawn for it."""
    kinds = ("pelvis", "spine") if condition == "strong-anatomy" else tuple(KIND_WEIGHTS)
    w = np.array([KIND_WEIGHTS[k] for k in kinds])
    kind = str(rng.choice(kinds, p=w / w.sum()))
    p_seed = int(rng.integers(2**31))
    model = patient_model(kind, p_seed, max(shape) * pixel / mag)
    model = over_body(model, box, shape, pixel, mag)
    landmark = None
    if condition == "strong-anatomy":
        model, landmark = _strong_placement(
            model, rng, ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2), shape, pixel, mag
        )
    thickness = 2 * model.body.half_depth * model.placement.scale
    # automatic exposure control raises the kV (and the beam hardens) through a thicker patient
    energy = float(np.clip(50.0 + 0.1 * (thickness - 150.0), 50.0, 70.0))
    tex = texture(shape, rng, pixel / mag / model.placement.scale)
    bg = render_patient(model, shape, pixel, mag, energy, tex)
    n_seeds = n_clips = 0
    if condition == "seeds-needle":
        c = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
        spread = 0.6 * max(box[2] - box[0], box[3] - box[1])
        n_seeds, n_clips = int(rng.integers(30, 101)), int(rng.integers(0, 4))
        bg = bg + seeds(shape, n_seeds, rng, c, spread, pixel, mag, energy)
        if n_clips:
            bg = bg + clips(shape, n_clips, rng, c, 1.5 * spread, pixel, mag, energy)
    sub = bg[::4, ::4]
    return bg, {
        "kind": kind,
        "seed": p_seed,
        "thickness_mm": thickness,
        "magnification": mag,
        "placement": asdict(model.placement),
        "landmark": landmark,
        "energy_kev": energy,
        "texture_amplitude": model.texture_amplitude,
        "seeds": n_seeds,
        "clips": n_clips,
        "line_integral": (float(bg.min()), float(np.percentile(sub, 99.9)), float(bg.max())),
    }
