"""A patient behind the fiducial: the line integral of a torso with its skeleton, lungs and gas.

:func:`patient` returns ``p(u, v) = Σ μ × chord`` (dimensionless, dense = bright, air = 0) of
one adult torso from the shoulders to the upper thighs, seen antero-posterior and cut to the
field of view of a ``kind`` of image (pelvis, spine, chest, abdomen). Everything is an exact
chord of a simple solid (:mod:`.solids`) times the μ of its material (:mod:`.materials`, NIST
SRD 126 at ``energy_kev``), so bone edges are sharp, cortical walls bright where the beam runs
along them and the range is the real one: 0 in the air beside the patient, 4–5 through
200–250 mm of soft tissue, 5–6 where bone adds to it (pelvis, spine), about 2 in the lungs.

The patient (a :class:`PatientModel`, reproducible by seed) is

- the body: an elliptic cylinder of soft tissue (ICRU-44) in a shell of fat, AP thickness
  150–320 mm, its width varying with height (waist, hips); a flank's skin edge may be in view;
- the spine T1–S1: vertebral bodies (elliptic columns with cortical walls and end plates),
  pedicles (cortical rings seen end-on: the AP view's "eyes"), laminae, spinous and
  transverse processes;
- twelve pairs of ribs (hollow tubes along circular arcs; posterior and anterior arcs cross),
  clavicles, scapulae;
- lungs (inflated lung: μ a quarter of soft tissue's) with the heart and the diaphragm domes
  pushing into them, pulmonary vessels, the trachea;
- the pelvis: iliac wings with their crests, the sacrum with its foramina, the pelvic brim,
  acetabula (hemispherical cortical cups), femoral heads, necks, trochanters and shafts,
  pubic bodies, superior and inferior rami, ischia (the obturator foramina between them);
- soft-tissue contrast: kidneys and psoas outlined by fat, the bladder;
- gas: colon (ascending, transverse, descending, rectum) with haustra and mottled stool,
  small-bowel loops, the stomach bubble;
- a trabecular texture (band-pass noise, ~0.5–2 mm) modulating the spongiosa of every bone.

Sizes are adult means with ±10 % spread and a whole-patient scale of 0.9–1.1. Sources:
vertebrae — Panjabi et al., Spine 16(8):888 (1991) thoracic and 17(3):299 (1992) lumbar
(body widths 26→50 mm T1→L5, heights 16→28 mm, pedicle widths 5–15 mm); discs — 5 mm
thoracic, 9–11 mm lumbar (Gray's Anatomy, 41st ed.); ribs — shaft 10–14 × 5–8 mm, cortex
~1 mm (Gray's); femur — head Ø 44–52 mm, neck Ø ~30 mm, neck–shaft angle 125–135°, shaft Ø
25–30 mm with 5–7 mm cortex (Gray's; Noble et al., Clin Orthop 235:148, 1988); pelvis —
inter-hip-centre distance 170–200 mm, obturator foramen ~45 × 30 mm, sacrum ~100 mm wide
(Gray's); trabecular bone density 1.18 g/cm³ (ICRU 46); lungs ~250 mm tall (Gray's).
μ of every material with its source: :mod:`.materials`.

:func:`seeds` and :func:`clips` draw brachytherapy seeds (titanium capsules 0.8 × 4.5 mm) and
surgical clips as supersampled line-integral images to add.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Literal, Sequence

import cv2
import numpy as np

from ..errors import InputError
from .materials import linear_attenuation
from .solids import Canal, Column, Ellipsoid, Tube, capsule_chord, capsule_volume

Kind = Literal["pelvis", "chest", "spine", "abdomen"]
KINDS: tuple[str, ...] = ("pelvis", "chest", "spine", "abdomen")
Shape = Ellipsoid | Tube | Column | Canal


@dataclass(frozen=True)
class Structure:
    """One part of the patient: a solid, the materials of its wall and core, the medium it
    displaces (its line integral is added as (μ_material − μ_medium) × chord) and whether the
    trabecular texture modulates its core."""

    name: str
    shape: Shape
    wall: str = "cortical_bone"
    core: str = "trabecular_bone"
    medium: str = "soft_tissue"
    textured: bool = True


@dataclass(frozen=True)
class BodySection:
    """The body (mm): an elliptic cylinder along the patient's y axis (cranio-caudal), half-width
    ``half_width`` (lateral) × ``half_depth`` (AP) at y = 0, a shell of fat ``fat`` thick; the
    half-width changes with height by ``1 + flare · tanh(y / 100 mm)`` (narrow waist, wide hips)."""

    half_width: float
    half_depth: float
    fat: float
    flare: float = 0.0
    center_x: float = 0.0


@dataclass(frozen=True)
class Placement:
    """Where the detector looks (mm, patient plane): the point at the image centre, the image's
    rotation about the beam (rad) and a left–right mirror; ``scale`` multiplies every size of the
    patient (its build)."""

    center: tuple[float, float]
    angle: float = 0.0
    mirror: bool = False
    scale: float = 1.0


@dataclass(frozen=True)
class PatientModel:
    """A whole patient (structures in the patient's own mm, y caudal, y = 0 at the top of S1), the
    view onto it, the lung field and its intruders (heart, diaphragm domes: they displace lung)."""

    kind: str
    body: BodySection
    structures: tuple[Structure, ...]
    lungs: tuple[Ellipsoid, ...]
    lung_intruders: tuple[Ellipsoid, ...]
    placement: Placement
    texture_amplitude: float = 0.06


#: range of the trabecular texture's relative amplitude (std of the core's line integral at
#: the 0.5–2 mm scale): a ray crosses ~L / 0.8 mm trabeculae 0.15 mm thick (BV/TV 10–25 %),
#: so the bone path along it fluctuates by ~√N × 0.15 mm ≈ 20 % of its mean, ~10–14 % after
#: averaging over a detector pixel's footprint; the bone is ~⅓ of a trabecular core's
#: attenuation (the rest is marrow), so the core's line integral fluctuates by ~3–10 %
TEXTURE_AMPLITUDE = (0.03, 0.10)


# ----------------------------------------------------------------------------- anatomy
def _j(rng: np.random.Generator, x: float, rel: float = 0.08) -> float:
    """``x`` with a relative Gaussian spread ``rel`` (clipped at ±2.5 σ)."""
    return float(x * (1.0 + rel * np.clip(rng.standard_normal(), -2.5, 2.5)))


def _levels(rng: np.random.Generator) -> list[dict]:
    """T1–L5 (top to bottom): body centre y, half-width, half-depth, half-height (mm); S1 top at y = 0."""
    out = []
    y = 0.0
    for k in range(17):  # from L5 (k = 0) upward
        lumbar = k < 5
        disc = _j(rng, 10.0 if lumbar else 5.0, 0.1)
        f = k / 4 if lumbar else (k - 5) / 11  # 0 at L5 / T12, 1 at L1 / T1
        height = _j(rng, (28 - 2 * f) if lumbar else (23 - 7 * f), 0.05)
        width = _j(rng, (50 - 8 * f) if lumbar else (40 - 14 * f), 0.05)
        depth = _j(rng, (35 - 3 * f) if lumbar else (30 - 13 * f), 0.05)
        y -= disc
        out.append(
            {
                "name": (f"L{5 - k}" if lumbar else f"T{17 - k}"),
                "y": y - height / 2,
                "a": width / 2,
                "c": depth / 2,
                "h": height / 2,
                "lumbar": lumbar,
            }
        )
        y -= height
    return out[::-1]


def _vertebra(rng: np.random.Generator, lv: dict, x0: float) -> list[Structure]:
    """Body, pedicles, laminae, spinous and transverse processes of one vertebra."""
    n, y, a, c, h, lumbar = lv["name"], lv["y"], lv["a"], lv["c"], lv["h"], lv["lumbar"]
    tilt = float(rng.normal(0, 0.03))
    out = [Structure(f"{n} body", Column((x0, y), a, c, h, tilt, wall=0.8, plate=1.0, plate_fill=0.5))]
    ped_w = _j(rng, 5.5 if lumbar else 3.0, 0.1)
    ped_h = _j(rng, 7.5 if lumbar else 6.0, 0.08)
    yp = y - 0.25 * h
    xp = 0.68 * a
    for s in (-1, 1):
        out.append(
            Structure(
                f"{n} pedicle", Canal((x0 + s * xp, yp), (ped_w, ped_h), 22.0 if lumbar else 16.0, tilt, wall=1.5)
            )
        )
        out.append(
            Structure(f"{n} lamina", Tube((x0 + s * xp, yp + ped_h), (x0 + s * 3.0, y + 0.9 * h), 4.0, 6.0, wall=1.2))
        )
        tp_len = _j(rng, 22.0 if lumbar else 14.0, 0.15)
        tip = (x0 + s * (xp + ped_w + tp_len), yp + (0.0 if lumbar else -4.0))
        out.append(
            Structure(
                f"{n} transverse process",
                Tube((x0 + s * (xp + ped_w), yp), tip, _j(rng, 4.5 if lumbar else 5.0), 5.0, wall=1.0),
            )
        )
    out.append(
        Structure(
            f"{n} spinous process",
            Ellipsoid((x0, y + 0.55 * h), (_j(rng, 4.5), _j(rng, 9.0)), 15.0 if lumbar else 11.0, tilt, wall=1.0),
        )
    )
    return out


def _circle(p1, p2, p3):
    """Centre and radius of the circle through three points (mm)."""
    (x1, y1), (x2, y2), (x3, y3) = p1, p2, p3
    d = 2 * (x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2))
    ux = ((x1 * x1 + y1 * y1) * (y2 - y3) + (x2 * x2 + y2 * y2) * (y3 - y1) + (x3 * x3 + y3 * y3) * (y1 - y2)) / d
    uy = ((x1 * x1 + y1 * y1) * (x3 - x2) + (x2 * x2 + y2 * y2) * (x1 - x3) + (x3 * x3 + y3 * y3) * (x2 - x1)) / d
    return (ux, uy), math.hypot(x1 - ux, y1 - uy)


def _arc_tube(name, p_start, p_mid, p_end, h, c, wall) -> Structure:
    """A tube along the circular arc through three points (start → mid → end)."""
    (cx, cy), r = _circle(p_start, p_mid, p_end)
    ang = [math.atan2(p[1] - cy, p[0] - cx) for p in (p_start, p_mid, p_end)]
    t0, tm, t1 = ang
    # go counter-clockwise from t0 to t1 if the mid-point lies on that way, else the other way round
    if (tm - t0) % (2 * math.pi) > (t1 - t0) % (2 * math.pi):
        t0, t1 = t1, t0
    t1 = t0 + (t1 - t0) % (2 * math.pi)
    return Structure(name, Tube((cx, cy), half_width=h, depth=c, wall=wall, radius=r, angles=(t0, t1)))


def _ribs(rng: np.random.Generator, levels: list[dict], half_width: float) -> list[Structure]:
    """Posterior arcs from the transverse processes out to the chest wall, anterior arcs from there
    down and in to the costal cartilage (ribs 1–10), and the short floating ribs 11–12."""
    out = []
    lateral = 0.88 * half_width
    for k in range(12):
        lv = levels[k]  # T1..T12
        y = lv["y"]
        # a rib slopes down and forward, so the beam crosses its 5–8 mm thickness obliquely
        h, c = _j(rng, 6.0 if k > 0 else 5.0), _j(rng, 5.5)
        # the chest is narrow at the top (ribs 1–3) and widest at ribs 7–9
        reach = lateral * (0.55 + 0.45 * math.sin(min(k + 1, 9) / 9 * math.pi / 2))
        for s in (-1, 1):
            x_in = s * (lv["a"] + 14.0)
            if k >= 10:  # floating ribs: short, sloping down and out
                out.append(
                    _arc_tube(
                        f"rib {k + 1}", (x_in, y), (s * (lv["a"] + 50), y + 14), (s * (lv["a"] + 85), y + 40), h, c, 1.0
                    )
                )
                continue
            drop = _j(rng, 35.0 + 3.0 * k, 0.1)
            p_lat = (s * reach, y + drop)
            out.append(
                _arc_tube(f"rib {k + 1} posterior", (x_in, y), (s * 0.6 * reach, y + 0.15 * drop - 6), p_lat, h, c, 1.0)
            )
            y_front = y + drop + _j(rng, 45.0 + 4.0 * k, 0.1)
            x_front = s * _j(rng, 35.0 + 5.0 * k, 0.1)
            p_mid = (s * 0.7 * reach, y + drop + 0.55 * (y_front - y - drop))
            out.append(_arc_tube(f"rib {k + 1} anterior", p_lat, p_mid, (x_front, y_front), h * 0.9, c * 0.8, 0.8))
    return out


def _shoulders(rng: np.random.Generator, levels: list[dict], half_width: float) -> list[Structure]:
    """Clavicles and scapulae."""
    out = []
    y1 = levels[0]["y"]
    for s in (-1, 1):
        out.append(
            _arc_tube(
                "clavicle",
                (s * 22, y1 - 18),
                (s * 80, y1 - 30),
                (s * 0.95 * half_width, y1 - 24),
                _j(rng, 6.5),
                6.0,
                1.8,
            )
        )
        ys = levels[4]["y"]
        out.append(
            Structure(
                "scapula",
                Ellipsoid((s * 0.78 * half_width, ys), (_j(rng, 45.0), _j(rng, 75.0)), 6.0, s * 0.25, wall=1.5),
            )
        )
        out.append(
            Structure(
                "scapular border",
                Tube((s * 0.95 * half_width, ys - 50), (s * 0.70 * half_width, ys + 70), 5.0, 7.0, wall=1.5),
            )
        )
    return out


def _pelvis(rng: np.random.Generator, levels: list[dict]) -> list[Structure]:
    """Sacrum (foramina), iliac wings and crests, pelvic brim, acetabula, femora, pubis, ischia."""
    out = _sacrum(rng)
    x_hip = _j(rng, 92.0, 0.05)
    y_hip = _j(rng, 105.0, 0.05)
    r_head = _j(rng, 24.0, 0.07)
    neck_angle = math.radians(float(rng.uniform(125, 135)))
    for s in (-1, 1):
        out += _iliac(rng, s, levels, y_hip)
        out += _hip(rng, s, (s * x_hip, y_hip), r_head, neck_angle)
        out += _pubis_and_ischium(rng, s, x_hip, y_hip)
    return out


def _sacrum(rng: np.random.Generator) -> list[Structure]:
    """The sacrum with its foramina, and the coccyx."""
    out = []
    # the sacrum: wide alae on top, narrowing to the apex (a wedge cut from an ellipsoid)
    a_s, b_s = _j(rng, 56.0, 0.06), _j(rng, 62.0, 0.06)
    out.append(
        Structure(
            "sacrum",
            Ellipsoid(
                (0.0, 50.0), (a_s, b_s), 18.0, 0.0, wall=1.5, clips=((0.8, 0.5, 0.55 * a_s), (-0.8, 0.5, 0.55 * a_s))
            ),
        )
    )
    out.append(Structure("coccyx", Tube((0.0, 105.0), (0.0, 135.0), 7.0, 7.0, wall=1.0)))
    for k, (yf, xf, rf) in enumerate(((16, 27, 5.5), (36, 23, 5.0), (55, 18, 4.0), (72, 13, 3.0))):
        for s in (-1, 1):
            # a foramen is a canal of soft tissue through the sacrum's spongiosa, ringed by cortex
            out.append(
                Structure(
                    f"sacral foramen S{k + 1}",
                    Canal((s * xf, yf), (rf, rf * 1.1), 14.0, wall=1.0),
                    wall="cortical_bone",
                    core="soft_tissue",
                    medium="trabecular_bone",
                    textured=False,
                )
            )
    return out


def _iliac(rng: np.random.Generator, s: int, levels: list[dict], y_hip: float) -> list[Structure]:
    """One side's iliac wing and crest and pelvic brim (``s`` = ±1: the side)."""
    out = []
    r_wing = _j(rng, 68.0, 0.06)
    cw = (s * _j(rng, 88.0, 0.05), levels[-1]["y"] - 20 + r_wing)
    # the wing is a fan: the inferior-medial part (the ilium's body) is cut off toward the hip
    # seen obliquely (the wing faces 40–50° off the coronal plane): a 10–20 mm chord of a thin
    # plate; its lower part runs into the acetabulum's roof and the sacro-iliac joint
    out.append(Structure("iliac wing", Ellipsoid(cw, (r_wing, r_wing), 10.0, 0.0, wall=2.0)))
    out.append(
        Structure(
            "iliac crest",
            Tube(
                cw,
                half_width=5.0,
                depth=8.0,
                wall=1.5,
                radius=r_wing - 5.0,
                angles=((math.pi * 1.05, math.pi * 1.9) if s > 0 else (math.pi * 1.10, math.pi * 1.95)),
            ),
        )
    )
    out.append(_arc_tube("pelvic brim", (s * 40, 12), (s * 58, 60), (s * 22, y_hip + 28), 2.5, 11.0, 1.0))
    return out


def _hip(
    rng: np.random.Generator, s: int, c_hip: tuple[float, float], r_head: float, neck_angle: float
) -> list[Structure]:
    """One side's acetabulum, femoral head, neck, trochanters and shaft (``s`` = ±1: the side)."""
    out = []
    out.append(
        Structure(
            "acetabulum",
            Ellipsoid(c_hip, (r_head + 6.0, r_head + 6.0), r_head + 6.0, 0.0, wall=3.5, clips=((s * 0.5, 1.0, 0.0),)),
        )
    )
    out.append(Structure("femoral head", Ellipsoid(c_hip, (r_head, r_head), r_head, 0.0, wall=1.2)))
    # the neck runs from the head down and out to the shaft, at the neck–shaft angle to it
    shaft = np.array([-s * 0.12, 1.0]) / math.hypot(0.12, 1.0)
    medial = np.array([-s * shaft[1], s * shaft[0]])  # across the shaft, toward the midline
    to_head = math.cos(neck_angle) * shaft + math.sin(neck_angle) * medial
    neck_len = _j(rng, 50.0, 0.08)
    junction = (c_hip[0] - neck_len * to_head[0], c_hip[1] - neck_len * to_head[1])
    out.append(Structure("femoral neck", Tube(c_hip, junction, _j(rng, 15.0, 0.06), 14.0, wall=2.0)))
    out.append(
        Structure(
            "greater trochanter",
            Ellipsoid(
                (junction[0] + s * 14.0, junction[1] - 12.0), (_j(rng, 17.0), _j(rng, 24.0)), 20.0, 0.0, wall=1.5
            ),
        )
    )
    shaft1 = (junction[0] + 400 * shaft[0], junction[1] + 400 * shaft[1])
    out.append(Structure("femoral shaft", Tube(junction, shaft1, _j(rng, 14.0, 0.06), 14.0, wall=_j(rng, 6.0, 0.1))))
    out.append(
        Structure(
            "lesser trochanter",
            Ellipsoid((junction[0] - s * 13.0, junction[1] + 30.0), (9.0, 11.0), 10.0, 0.0, wall=1.2),
        )
    )
    return out


def _pubis_and_ischium(rng: np.random.Generator, s: int, x_hip: float, y_hip: float) -> list[Structure]:
    """One side's pubic rami and body and ischium, around the obturator foramen (``s`` = ±1)."""
    out = []
    out.append(
        Structure(
            "superior pubic ramus",
            Tube((s * (x_hip - 22), y_hip + 10), (s * 14.0, y_hip + 38), _j(rng, 8.5), 10.0, wall=1.5),
        )
    )
    out.append(Structure("pubic body", Ellipsoid((s * 17.0, y_hip + 55), (12.0, 24.0), 12.0, 0.0, wall=1.5)))
    out.append(
        Structure(
            "inferior pubic ramus",
            Tube((s * 16.0, y_hip + 75), (s * (x_hip - 38), y_hip + 95), _j(rng, 7.0), 9.0, wall=1.5),
        )
    )
    out.append(
        Structure(
            "ischium",
            Tube((s * (x_hip - 38), y_hip + 95), (s * (x_hip - 18), y_hip + 22), _j(rng, 11.0), 14.0, wall=1.8),
        )
    )
    return out


def _lungs(rng: np.random.Generator, levels: list[dict], body: BodySection):
    """Lungs, the heart and diaphragm domes that displace them, vessels, trachea and bronchi.

    A lung is an ellipsoid from above T1 down to the costophrenic recess at T12, inside the
    rib cage (its lateral edge 20–30 mm inside the skin, its depth 70 % of the body's there);
    the dome of the diaphragm (liver on the right, a little lower on the left) rises to T9–T10
    medially and the heart sits left of the midline, both carving the lung's base and border.
    """
    y_top, y_base = levels[0]["y"] - 25.0, levels[11]["y"]
    b = (y_base - y_top) / 2
    y_mid = y_top + b
    hw = body.half_width * (1.0 + body.flare * math.tanh(y_mid / 100.0))
    lungs, intruders, vessels = [], [], []
    for s in (-1, 1):
        x_in = levels[5]["a"] + 12.0
        x_out = hw - _j(rng, 25.0, 0.2)
        a = (x_out - x_in) / 2
        cx = s * (x_in + a)
        depth = 0.7 * body.half_depth * math.sqrt(max(1 - (abs(cx) / hw) ** 2, 0.1))
        lungs.append(Ellipsoid((cx, y_mid), (a, b), depth, 0.0))
        y_dome = levels[9]["y"] + (0.0 if s < 0 else 12.0)
        intruders.append(
            Ellipsoid(
                (s * 0.35 * x_out, y_dome + 95.0), (_j(rng, 0.75 * x_out, 0.05), 95.0), 1.2 * body.half_depth, 0.0
            )
        )
        hilum = (s * (levels[4]["a"] + 25), levels[5]["y"])
        for _ in range(int(rng.integers(12, 20))):
            th = float(rng.uniform(-1.2, 1.2))
            r = float(rng.uniform(40, 110))
            start = (hilum[0] + s * float(rng.uniform(0, 15)), hilum[1] + float(rng.normal(0, 12)))
            end = (start[0] + s * r * math.cos(th), start[1] + r * math.sin(th))
            vessels.append(
                Structure(
                    "pulmonary vessel",
                    Tube(start, end, float(rng.uniform(1.5, 4.0)), 3.0),
                    wall="soft_tissue",
                    core="soft_tissue",
                    medium="lung",
                    textured=False,
                )
            )
    intruders.append(
        Ellipsoid(
            (_j(rng, 30.0, 0.2), levels[8]["y"] + 15), (_j(rng, 62.0), _j(rng, 52.0)), 0.6 * body.half_depth, -0.5
        )
    )
    air = [
        Structure(
            "trachea", Tube((0.0, y_top - 60), (0.0, levels[4]["y"]), 8.5, 8.5), wall="air", core="air", textured=False
        )
    ]
    for s in (-1, 1):
        air.append(
            Structure(
                "main bronchus",
                Tube((0.0, levels[4]["y"]), (s * 40.0, levels[5]["y"] + 8), 6.0, 6.0),
                wall="air",
                core="air",
                textured=False,
            )
        )
    return tuple(lungs), tuple(intruders), vessels + air


def _soft_outlines(rng: np.random.Generator, levels: list[dict]) -> list[Structure]:
    """Organs outlined by fat: kidneys, psoas margins, bladder."""
    out = []
    y_l1 = levels[12]["y"]
    for s in (-1, 1):
        ck = (s * _j(rng, 65.0), y_l1 + (10.0 if s < 0 else -5.0))
        out.append(
            Structure(
                "kidney",
                Ellipsoid(ck, (_j(rng, 30.0), _j(rng, 55.0)), 28.0, s * 0.25, wall=5.0),
                wall="adipose",
                core="soft_tissue",
                textured=False,
            )
        )
        out.append(
            Structure(
                "psoas margin",
                Tube((s * 22.0, levels[11]["y"]), (s * 62.0, 30.0), 3.0, 40.0),
                wall="adipose",
                core="adipose",
                textured=False,
            )
        )
    out.append(
        Structure(
            "bladder",
            Ellipsoid((0.0, 140.0), (_j(rng, 45.0, 0.15), _j(rng, 35.0, 0.15)), 40.0, 0.0, wall=3.0),
            wall="adipose",
            core="soft_tissue",
            textured=False,
        )
    )
    return out


def _gas(rng: np.random.Generator, levels: list[dict], half_width: float) -> list[Structure]:
    """Colon gas in haustral segments with stool mottling, small-bowel loops, the stomach bubble."""

    def gas(name, shape):
        return Structure(name, shape, wall="air", core="air", textured=False)

    out = []
    y_t12 = levels[11]["y"]
    xr, xl = -0.62 * half_width, 0.65 * half_width
    colon = [
        ((xr, 30.0), (xr, y_t12 + 40)),
        ((xr, y_t12 + 40), (0.0, y_t12 + 75)),
        ((0.0, y_t12 + 75), (xl, y_t12 + 20)),
        ((xl, y_t12 + 20), (xl, 20.0)),
        ((xl, 20.0), (10.0, 75.0)),
        ((0.0, 70.0), (0.0, 150.0)),
    ]
    for p0, p1 in colon:
        L = math.dist(p0, p1)
        n = max(1, int(L // 28))
        for k in range(n):
            if rng.random() > 0.55:
                continue
            f0, f1 = k / n, (k + 0.8) / n
            a = (p0[0] + f0 * (p1[0] - p0[0]), p0[1] + f0 * (p1[1] - p0[1]))
            b = (p0[0] + f1 * (p1[0] - p0[0]), p0[1] + f1 * (p1[1] - p0[1]))
            w = float(rng.uniform(10, 24))
            out.append(gas("colon gas", Tube(a, b, w, float(rng.uniform(10, 22)))))
            if rng.random() < 0.5:  # stool: gas bubbles in a soft mass
                for _ in range(int(rng.integers(8, 25))):
                    t = float(rng.random())
                    c = (
                        a[0] + t * (b[0] - a[0]) + rng.normal(0, w / 2),
                        a[1] + t * (b[1] - a[1]) + rng.normal(0, w / 2),
                    )
                    r = float(rng.uniform(1.5, 4.5))
                    out.append(gas("stool gas", Ellipsoid(c, (r, r), r)))
    for _ in range(int(rng.integers(0, 6))):  # small-bowel loops around the umbilicus
        c = (float(rng.normal(0, 50)), float(rng.normal(levels[14]["y"], 50)))
        r = float(rng.uniform(15, 35))
        t0 = float(rng.uniform(0, 2 * math.pi))
        out.append(
            gas(
                "small-bowel gas",
                Tube(
                    c,
                    half_width=float(rng.uniform(7, 13)),
                    depth=float(rng.uniform(7, 12)),
                    radius=r,
                    angles=(t0, t0 + float(rng.uniform(1.0, 3.5))),
                ),
            )
        )
    out.append(
        gas(
            "stomach bubble",
            Ellipsoid((0.45 * half_width, levels[10]["y"] + 20), (_j(rng, 35.0, 0.2), _j(rng, 22.0, 0.2)), 22.0),
        )
    )
    return out


_VIEW = {  # kind → (x range of the view centre, y range, AP thickness range (mm))
    "pelvis": ((-60.0, 60.0), (50.0, 140.0), (190.0, 240.0)),
    "spine": ((-25.0, 25.0), (-230.0, -60.0), (190.0, 240.0)),
    "abdomen": ((-70.0, 70.0), (-220.0, -20.0), (150.0, 300.0)),
    "chest": ((-40.0, 40.0), (-470.0, -330.0), (190.0, 250.0)),
}


def patient_model(
    kind: Kind = "pelvis", seed: int = 0, field_mm: float = 340.0, skin_edge: bool | None = None
) -> PatientModel:
    """A random adult (reproducible by ``seed``) and a view of ``kind`` onto it (see the module).

    ``field_mm`` is the field of view's width at the patient (mm), used to put one flank's skin
    edge inside it when ``skin_edge`` is True (default: pelvis and spine yes, chest and abdomen
    one time in three), which gives the image its air-to-bone dynamic range.
    """
    if kind not in _VIEW:
        raise InputError(None, "kind", f"one of {', '.join(KINDS)}, got {kind!r}")
    rng = np.random.default_rng([int(seed), 7])
    (x_rng, y_rng, t_rng) = _VIEW[kind]
    thickness = float(rng.uniform(*t_rng))
    half_width = thickness * float(rng.uniform(0.68, 0.82))
    body = BodySection(
        half_width, thickness / 2, float(rng.uniform(8, 12 + 0.12 * (thickness - 160))), float(rng.uniform(0.0, 0.08))
    )
    levels = _levels(rng)
    structures: list[Structure] = []
    for lv in levels:
        structures += _vertebra(rng, lv, 0.0)
    structures += _ribs(rng, levels, half_width) + _shoulders(rng, levels, half_width) + _pelvis(rng, levels)
    lungs, intruders, lung_parts = _lungs(rng, levels, body)
    structures += lung_parts + _soft_outlines(rng, levels) + _gas(rng, levels, half_width)
    scale = float(rng.uniform(0.9, 1.1))
    cx, cy = float(rng.uniform(*x_rng)), float(rng.uniform(*y_rng))
    if skin_edge is None:
        skin_edge = kind in ("pelvis", "spine") or rng.random() < 1 / 3
    if skin_edge:
        # shift the view sideways until one flank lies 5–30 % of the field inside its edge
        half_field = 0.5 * field_mm / scale
        inside = float(rng.uniform(0.05, 0.3)) * field_mm / scale
        need = half_width * (1 + body.flare * math.tanh(cy / 100)) - half_field + inside
        cx = math.copysign(max(abs(cx), need), cx if cx != 0 else 1.0)
    angle = float(rng.normal(0, 0.12)) if rng.random() < 0.7 else float(rng.uniform(-math.pi, math.pi))
    placement = Placement((cx, cy), angle, bool(rng.random() < 0.5), scale)
    return PatientModel(
        kind, body, tuple(structures), lungs, intruders, placement, float(rng.uniform(*TEXTURE_AMPLITUDE))
    )


def place_at(
    model: PatientModel,
    point_mm: tuple[float, float],
    pixel_uv: tuple[float, float],
    shape: tuple[int, int],
    pixel_mm: float,
    magnification: float,
) -> PatientModel:
    """``model`` with its view shifted so that the patient point ``point_mm`` (patient mm)
    images at pixel ``pixel_uv`` (u, v); rotation, mirror and scale are kept."""
    grid = _Grid.of(shape, model.placement, pixel_mm, magnification)
    u, v = pixel_uv
    x = grid.x0 + grid.xu * u + grid.xv * v
    y = grid.y0 + grid.yu * u + grid.yv * v
    c = model.placement.center
    new = Placement(
        (c[0] + point_mm[0] - x, c[1] + point_mm[1] - y),
        model.placement.angle,
        model.placement.mirror,
        model.placement.scale,
    )
    return PatientModel(
        model.kind, model.body, model.structures, model.lungs, model.lung_intruders, new, model.texture_amplitude
    )


def over_body(
    model: PatientModel,
    pixel_box: tuple[float, float, float, float],
    shape: tuple[int, int],
    pixel_mm: float,
    magnification: float,
    margin_mm: float = 40.0,
) -> PatientModel:
    """``model`` with its view shifted sideways, if need be, so that the image box (u0, v0, u1, v1)
    lies over the body at least ``margin_mm`` inside its skin (a fiducial over the air beside the
    patient would sit in the saturated direct beam)."""
    grid = _Grid.of(shape, model.placement, pixel_mm, magnification)
    u0, v0, u1, v1 = pixel_box
    corners = np.array([[u0, v0], [u1, v0], [u0, v1], [u1, v1]], float)
    x = grid.x0 + grid.xu * corners[:, 0] + grid.xv * corners[:, 1]
    y = grid.y0 + grid.yu * corners[:, 0] + grid.yv * corners[:, 1]
    b = model.body
    hw = b.half_width * (1.0 + b.flare * np.tanh(y / 100.0)) - margin_mm / model.placement.scale
    over = np.maximum(np.abs(x - b.center_x) - hw, 0.0)
    if not over.any():
        return model
    k = int(np.argmax(over))
    shift = math.copysign(float(over[k]), x[k] - b.center_x)  # move the view toward the midline
    c = model.placement.center
    new = Placement((c[0] - shift, c[1]), model.placement.angle, model.placement.mirror, model.placement.scale)
    return PatientModel(
        model.kind, model.body, model.structures, model.lungs, model.lung_intruders, new, model.texture_amplitude
    )


def structure_center(st: Structure) -> tuple[float, float]:
    """The centre (patient mm) of a structure's bounding box."""
    x0, x1, y0, y1 = st.shape.extent()
    return (x0 + x1) / 2, (y0 + y1) / 2


# ----------------------------------------------------------------------------- rendering
@dataclass(frozen=True)
class _Grid:
    """Image pixel (u, v) → patient mm (x, y) = (x0 + xu u + xv v, y0 + yu u + yv v)."""

    x0: float
    xu: float
    xv: float
    y0: float
    yu: float
    yv: float
    px: float  # pixel size at the patient, patient mm

    @classmethod
    def of(cls, shape, placement: Placement, pixel_mm: float, magnification: float) -> "_Grid":
        H, W = shape
        s = pixel_mm / magnification / placement.scale
        ca, sa = math.cos(placement.angle), math.sin(placement.angle)
        m = -1.0 if placement.mirror else 1.0
        # image offsets (du, dv)·s, rotated, x mirrored, then shifted to the view centre
        xu, xv = m * s * ca, -m * s * sa
        yu, yv = s * sa, s * ca
        x0 = placement.center[0] - xu * (W - 1) / 2 - xv * (H - 1) / 2
        y0 = placement.center[1] - yu * (W - 1) / 2 - yv * (H - 1) / 2
        return cls(x0, xu, xv, y0, yu, yv, s)

    def box(self, extent, shape):
        """Pixel rows/columns (slices) covering a patient-mm extent, clipped to the image; None if outside."""
        x_min, x_max, y_min, y_max = extent
        det = self.xu * self.yv - self.xv * self.yu
        us, vs = [], []
        for x in (x_min, x_max):
            for y in (y_min, y_max):
                dx, dy = x - self.x0, y - self.y0
                us.append((dx * self.yv - dy * self.xv) / det)
                vs.append((-dx * self.yu + dy * self.xu) / det)
        H, W = shape
        u0, u1 = max(int(math.floor(min(us))) - 1, 0), min(int(math.ceil(max(us))) + 2, W)
        v0, v1 = max(int(math.floor(min(vs))) - 1, 0), min(int(math.ceil(max(vs))) + 2, H)
        if u0 >= u1 or v0 >= v1:
            return None
        return slice(v0, v1), slice(u0, u1)

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        """Image pixels (n, 2) (u, v) of patient-mm points (n, 2)."""
        det = self.xu * self.yv - self.xv * self.yu
        dx, dy = xy[:, 0] - self.x0, xy[:, 1] - self.y0
        return np.c_[(dx * self.yv - dy * self.xv) / det, (-dx * self.yu + dy * self.xu) / det]

    def coords(self, rows: slice, cols: slice):
        """Patient mm (x, y) of the pixels in a box, float32 (h, w)."""
        u = np.arange(cols.start, cols.stop, dtype=np.float32)[None, :]
        v = np.arange(rows.start, rows.stop, dtype=np.float32)[:, None]
        return (
            np.float32(self.x0) + np.float32(self.xu) * u + np.float32(self.xv) * v,
            np.float32(self.y0) + np.float32(self.yu) * u + np.float32(self.yv) * v,
        )


def _body_image(body: BodySection, grid: _Grid, shape, mu_fat: float, mu_soft: float) -> np.ndarray:
    H, W = shape
    x, y = grid.coords(slice(0, H), slice(0, W))
    a = body.half_width * (1.0 + body.flare * np.tanh(y / 100.0))
    dx = x - body.center_x
    outer = 2 * body.half_depth * np.sqrt(np.maximum(1 - (dx / a) ** 2, 0))
    ai, bi = a - body.fat, body.half_depth - body.fat
    inner = 2 * bi * np.sqrt(np.maximum(1 - (dx / ai) ** 2, 0))
    return (mu_fat * (outer - inner) + mu_soft * inner).astype(np.float32)


@functools.lru_cache(maxsize=4)
def _texture_tile(shape: tuple[int, int], px_mm: float) -> np.ndarray:
    n = np.random.default_rng(20240611).standard_normal(shape, dtype=np.float32)
    s1, s2 = max(0.5 / px_mm, 0.6), max(2.0 / px_mm, 1.5)
    t = cv2.GaussianBlur(n, (0, 0), s1) - cv2.GaussianBlur(n, (0, 0), s2)
    t /= max(float(t.std()), 1e-12)
    t.flags.writeable = False
    return t


def texture(shape: tuple[int, int], rng: np.random.Generator, px_mm: float) -> np.ndarray:
    """Trabecular texture (H, W) float32, zero mean, unit standard deviation: white noise
    band-passed between ~0.5 and ~2 mm (difference of Gaussians) at ``px_mm`` mm per pixel.

    A random crop (offset and flip drawn from ``rng``) of one cached field twice the
    image's size, so a benchmark's thousands of images do not each filter a fresh one.
    """
    H, W = int(shape[0]), int(shape[1])
    side = 2 * max(H, W)
    # the band's scale is loose: pixel sizes within 0.05 mm share a field
    tile = _texture_tile((side, side), max(0.05, round(float(px_mm) / 0.05) * 0.05))
    r0, c0 = int(rng.integers(0, side - H + 1)), int(rng.integers(0, side - W + 1))
    out = tile[r0 : r0 + H, c0 : c0 + W]
    return out[::-1] if rng.random() < 0.5 else out


def render_patient(
    model: PatientModel,
    shape: tuple[int, int] = (1024, 1024),
    pixel_mm: float = 0.44,
    magnification: float = 1.3,
    energy_kev: float = 60.0,
    texture_field: np.ndarray | None = None,
) -> np.ndarray:
    """Line integral (H, W) float32 of ``model`` (dimensionless, dense = bright) on a detector of
    ``pixel_mm`` pixels with the patient plane magnified ``magnification`` times.

    ``texture_field`` (H, W) (zero mean, unit spread; None: no texture) modulates every textured
    core by ``1 + model.texture_amplitude × texture``.
    """
    grid = _Grid.of(shape, model.placement, pixel_mm, magnification)
    mu = {
        m: linear_attenuation(m, energy_kev)
        for m in ("soft_tissue", "adipose", "lung", "cortical_bone", "trabecular_bone", "air")
    }
    k = model.placement.scale  # chords in the patient's own mm → real mm
    out = k * _body_image(model.body, grid, shape, mu["adipose"], mu["soft_tissue"])
    # lungs: the lung chord less the heart's and domes' (they displace lung), never below zero
    for el in model.lungs:
        box = grid.box(el.extent(), shape)
        if box is None:
            continue
        x, y = grid.coords(*box)
        lung = sum(el.chords(x, y, grid.px)) - sum(sum(i.chords(x, y, grid.px)) for i in model.lung_intruders)
        out[box] += (k * (mu["lung"] - mu["soft_tissue"])) * np.maximum(lung, 0.0)
    for st in model.structures:
        box = grid.box(st.shape.extent(), shape)
        if box is None:
            continue
        d_wall, d_core = k * (mu[st.wall] - mu[st.medium]), k * (mu[st.core] - mu[st.medium])
        tex = texture_field if st.textured and texture_field is not None and d_core != 0 else None
        if isinstance(st.shape, Tube):
            _add_tube(out, st.shape, box, grid, d_wall, d_core, tex, model.texture_amplitude)
            continue
        x, y = grid.coords(*box)
        wall, core = st.shape.chords(x, y, grid.px)
        if tex is not None:
            core = core * (1.0 + model.texture_amplitude * tex[box])
        out[box] += d_wall * wall + d_core * core
    return np.maximum(out, 0.0)


def _add_tube(
    out: np.ndarray,
    tube: Tube,
    box,
    grid: _Grid,
    d_wall: float,
    d_core: float,
    tex: np.ndarray | None,
    amplitude: float,
) -> None:
    """Add a tube's line integral, evaluated only on the pixels of a band drawn along its
    centre-line (a long thin arc fills a few per cent of its bounding box)."""
    rows, cols = box
    line, sag = tube.centerline()
    uv = grid.pixels(line) - [cols.start, rows.start]
    reach = (tube.half_width + sag) / grid.px + 2.0
    mask = np.zeros((rows.stop - rows.start, cols.stop - cols.start), np.uint8)
    shift = 4  # OpenCV's sub-pixel vertices: 1/16 px
    pts = np.rint(uv * (1 << shift)).astype(np.int32).reshape(-1, 1, 2)
    cv2.polylines(mask, [pts], False, 1, thickness=int(2 * math.ceil(reach) + 1), lineType=cv2.LINE_8, shift=shift)
    for p in (pts[0, 0], pts[-1, 0]):  # round ends
        cv2.circle(mask, (int(p[0]), int(p[1])), int(math.ceil(reach)) << shift, 1, -1, cv2.LINE_8, shift)
    jj, ii = np.nonzero(mask)
    if len(jj) == 0:
        return
    r, c = jj + rows.start, ii + cols.start
    u, v = c.astype(np.float32), r.astype(np.float32)
    x = np.float32(grid.x0) + np.float32(grid.xu) * u + np.float32(grid.xv) * v
    y = np.float32(grid.y0) + np.float32(grid.yu) * u + np.float32(grid.yv) * v
    wall, core = tube.chords(x, y, grid.px)
    if tex is not None:
        core = core * (1.0 + amplitude * tex[r, c])
    out[r, c] += d_wall * wall + d_core * core


def patient(
    shape: tuple[int, int] = (1024, 1024),
    seed: int = 0,
    kind: Kind = "pelvis",
    pixel_mm: float = 0.44,
    energy_kev: float = 60.0,
    magnification: float = 1.3,
    skin_edge: bool | None = None,
    textured: bool = True,
) -> np.ndarray:
    """A patient's line integral (H, W) float32 (dense = bright, 0 in air), reproducible by ``seed``.

    Parameters
    ----------
    shape : image (rows, columns).
    seed : the patient, the view onto it and the texture.
    kind : where the view is centred: ``pelvis`` (iliac crests to upper femora), ``spine``
        (lower thoracic and lumbar spine), ``abdomen``, ``chest``.
    pixel_mm : detector pixel pitch (mm); ``magnification`` maps the patient plane onto it.
    energy_kev : effective energy (40–100 keV) for the μ of every tissue.
    skin_edge : put one flank's skin edge in view (None: pelvis/spine yes, else one in three).
    textured : modulate the spongiosa by the trabecular texture.

    Returns
    -------
    np.ndarray (H, W) float32: Σ μ × chord through the patient.
    """
    H, W = int(shape[0]), int(shape[1])
    if H < 8 or W < 8:
        raise InputError(None, "shape", f"an image of at least 8 × 8 pixels, got {shape!r}")
    if not (pixel_mm > 0 and magnification >= 1.0):
        raise InputError(None, "pixel_mm / magnification", "a positive pixel size and a magnification ≥ 1")
    field = max(H, W) * pixel_mm / magnification
    model = patient_model(kind, seed, field, skin_edge)
    tex = None
    if textured:
        tex = texture((H, W), np.random.default_rng([int(seed), 11]), pixel_mm / magnification / model.placement.scale)
    return render_patient(model, (H, W), pixel_mm, magnification, energy_kev, tex)


# ----------------------------------------------------------------------------- implants
def _capsules_image(shape, p0: np.ndarray, p1: np.ndarray, radius: float, mu: float, supersample: int) -> np.ndarray:
    """Line integral (H, W) of capsules p0[k]→p1[k] (pixels in x, y; depth in px too), radius
    ``radius`` px, μ per pixel length ``mu``, each pixel the mean of supersample² sub-samples."""
    H, W = shape
    out = np.zeros((H, W), np.float64)
    s = int(supersample)
    o = (np.arange(s) + 0.5) / s - 0.5
    ou, ov = np.meshgrid(o, o)
    for a, b in zip(p0, p1):
        lo = np.floor(np.minimum(a[:2], b[:2]) - radius - 1).astype(int)
        hi = np.ceil(np.maximum(a[:2], b[:2]) + radius + 1).astype(int)
        u0, v0 = max(lo[0], 0), max(lo[1], 0)
        u1, v1 = min(hi[0] + 1, W), min(hi[1] + 1, H)
        if u0 >= u1 or v0 >= v1:
            continue
        u = np.arange(u0, u1)[None, :, None] + ou.ravel()[None, None, :]
        v = np.arange(v0, v1)[:, None, None] + ov.ravel()[None, None, :]
        ch = capsule_chord(
            np.broadcast_to(u, (v1 - v0, u1 - u0, s * s)), np.broadcast_to(v, (v1 - v0, u1 - u0, s * s)), a, b, radius
        )
        out[v0:v1, u0:u1] += mu * ch.mean(-1)
    return out.astype(np.float32)


def _region(shape, rng, center_px, spread_px, n):
    H, W = shape
    c = np.array(center_px if center_px is not None else ((W - 1) / 2, (H - 1) / 2), float)
    r = float(spread_px if spread_px is not None else 0.15 * min(H, W))
    ang = rng.uniform(0, 2 * np.pi, n)
    rad = r * np.sqrt(rng.uniform(0, 1, n))
    return c + np.c_[rad * np.cos(ang), rad * np.sin(ang)]


def _directions(rng, n):
    d = rng.standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def seeds(
    shape: tuple[int, int],
    n: int,
    rng: np.random.Generator,
    center_px: Sequence[float] | None = None,
    spread_px: float | None = None,
    pixel_mm: float = 0.44,
    magnification: float = 1.3,
    energy_kev: float = 60.0,
    length_mm: float = 4.5,
    diameter_mm: float = 0.8,
    material: str = "titanium",
    supersample: int = 4,
) -> np.ndarray:
    """Brachytherapy seeds as a line-integral image (H, W) float32 to add to a background.

    ``n`` capsules (``length_mm`` end to end, ``diameter_mm``; default the 0.8 × 4.5 mm of an
    I-125 seed, modelled as solid ``material`` — titanium) with uniformly random 3-D
    orientations, their centres uniform in a disc of radius ``spread_px`` (default 15 % of the
    image) about ``center_px`` (u, v) (default the centre), magnified ``magnification`` times
    onto ``pixel_mm`` pixels. Each pixel is the mean of ``supersample``² sub-samples, so the
    image's sum is μ × volume × M² / pixel area.
    """
    if n < 0 or supersample < 1:
        raise InputError(None, "n / supersample", "a non-negative count and a positive supersampling")
    px = pixel_mm / magnification  # mm at the seed per detector pixel
    r = diameter_mm / 2 / px
    half = (length_mm / 2 - diameter_mm / 2) / px  # half the capsule's axis, pixels
    c = _region(shape, rng, center_px, spread_px, n)
    d = _directions(rng, n)
    # seeds sit at different depths (solid capsules never share space): ±20 mm about the plane
    centers = np.c_[c, rng.uniform(-20.0, 20.0, n) / px]
    mu = linear_attenuation(material, energy_kev) * px
    return _capsules_image(shape, centers - half * d, centers + half * d, r, mu, supersample)


def clips(
    shape: tuple[int, int],
    n: int,
    rng: np.random.Generator,
    center_px: Sequence[float] | None = None,
    spread_px: float | None = None,
    pixel_mm: float = 0.44,
    magnification: float = 1.3,
    energy_kev: float = 60.0,
    leg_mm: float = 7.0,
    wire_mm: float = 0.8,
    material: str = "titanium",
    supersample: int = 4,
) -> np.ndarray:
    """Closed surgical (ligation) clips as a line-integral image (H, W) float32: each two
    touching parallel legs (capsules ``leg_mm`` long end to end, ``wire_mm`` thick), randomly
    oriented at random depths (±20 mm), placed as in :func:`seeds`."""
    if n < 0 or supersample < 1:
        raise InputError(None, "n / supersample", "a non-negative count and a positive supersampling")
    px = pixel_mm / magnification
    r = wire_mm / 2 / px
    half = (leg_mm / 2 - wire_mm / 2) / px
    c = np.c_[_region(shape, rng, center_px, spread_px, n), rng.uniform(-20.0, 20.0, n) / px]
    d = _directions(rng, n)
    q = np.cross(d, _directions(rng, n))
    q /= np.linalg.norm(q, axis=1, keepdims=True)  # the side the second leg lies on
    p0, p1 = [], []
    for s in (-1.0, 1.0):
        mid = c + s * r * q  # the legs' axes 2 r apart: touching
        p0.append(mid - half * d)
        p1.append(mid + half * d)
    mu = linear_attenuation(material, energy_kev) * px
    return _capsules_image(shape, np.concatenate(p0), np.concatenate(p1), r, mu, supersample)


def seed_line_integral_sum(
    n: int,
    pixel_mm: float = 0.44,
    magnification: float = 1.3,
    energy_kev: float = 60.0,
    length_mm: float = 4.5,
    diameter_mm: float = 0.8,
    material: str = "titanium",
) -> float:
    """The sum over the image of :func:`seeds`' line integral when all ``n`` lie inside it:
    n × μ × capsule volume / (pixel area at the seeds)."""
    px = pixel_mm / magnification
    return n * linear_attenuation(material, energy_kev) * capsule_volume(length_mm, diameter_mm / 2) / (px * px)
