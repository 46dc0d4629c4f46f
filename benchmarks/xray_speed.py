"""How fast does the radiograph simulator render a 1024 × 1024 image? (target ≤ 50 ms)

ftrac_2005 with its body at workspace poses, the default imaging model (60 keV, 0.6 mm focal
spot, σ 0.7 px detector blur, 10⁴ quanta per pixel, 16-bit raw), measured in-process:

- noise-free: line integrals (5 × 5 sub-samples at wires, beads and body edges), their
  transmissions blurred and integrated over the pixels, log and raw outputs;
- full model: the same plus quantum noise, raw quantisation and the log image from it;
- full model over an anatomy-like background (pre-generated, as a study would reuse it);
- the geometry alone (``line_integral_box``).

Baseline, measured in the same run on a few of the same poses: the simulator one writes
first — the same exact chords in their textbook form (``geometry.tube_chord`` /
``sphere_chord`` / ``cylinder_z_chord`` on (N, 3) ray arrays), each bead and wire piece over
its own bounding box, on one fine grid of 5 × 5 points per pixel over the whole image (body
included), the transmission blurred on that grid (float64 Gaussian), summed over each pixel,
and Poisson noise on every pixel.

Every figure is the best of ROUNDS rounds (the machine is shared); CPU seconds of this
process are printed beside wall-clock ones.

Run: ``.venv/bin/python benchmarks/xray_speed.py``
"""

from __future__ import annotations

import math
import time

import numpy as np
from _common import load, machine
from scipy.ndimage import gaussian_filter

from ftrac_design.pose.camera import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.xray import ImagingModel, anatomy, line_integral_box, render
from ftrac_design.xray.geometry import cylinder_z_chord, sphere_chord, tube_chord
from ftrac_design.xray.rays import Rays, feature_pieces
from ftrac_design.xray.render import blur_sigma_px

N_POSES = 20
N_BASELINE = 3
ROUNDS = 3


def baseline_render(features, R, t, cam, imaging, rng):
    """The straightforward simulator (see module): same physics, no footprints or fast paths."""
    body = features.body
    H, W = imaging.image_shape
    rays = Rays(cam, R, t)
    s = int(imaging.supersample)
    centers, radii, pieces = feature_pieces(features, imaging.mu("steel"))
    su, sv = blur_sigma_px(cam, imaging, float(t[2]))
    p = np.zeros((H * s, W * s))  # s × s points per pixel, every pixel

    def box_of(P, pad):
        uv = cam.project(P @ R.T + t)
        lo = np.maximum(np.floor(uv.min(0) - pad).astype(int), 0)
        hi = np.minimum(np.ceil(uv.max(0) + pad).astype(int), [W - 1, H - 1])
        return lo, hi

    def add(lo, hi, chord):
        fu = (np.arange(lo[0] * s, (hi[0] + 1) * s) + 0.5) / s - 0.5
        fv = (np.arange(lo[1] * s, (hi[1] + 1) * s) + 0.5) / s - 0.5
        U, V = np.meshgrid(fu, fv)
        d = rays(U.ravel(), V.ravel())
        p[lo[1] * s : (hi[1] + 1) * s, lo[0] * s : (hi[0] + 1) * s] += chord(d).reshape(U.shape)

    for k in range(len(pieces.L)):
        ends = np.stack([pieces.a[k], pieces.a[k] + pieces.L[k] * pieces.e[k]])

        def tube(d, k=k):
            n = len(d)
            return pieces.mu[k] * tube_chord(
                rays.c,
                d,
                np.broadcast_to(pieces.a[k], (n, 3)),
                np.broadcast_to(pieces.e[k], (n, 3)),
                np.full(n, pieces.L[k]),
                np.full(n, pieces.r[k]),
                np.broadcast_to(pieces.n0[k], (n, 3)),
                np.broadcast_to(pieces.n1[k], (n, 3)),
            )

        add(*box_of(ends, 4), tube)
    for q, r in zip(centers, radii):
        add(*box_of(q[None], 8), lambda d, q=q, r=r: imaging.mu("steel") * sphere_chord(rays.c, d, q, r))
    ro, h = body.outer_diameter / 2, body.length / 2
    corners = np.array([[x, y, z] for x in (-ro, ro) for y in (-ro, ro) for z in (-h, h)])
    rb = body.bore_diameter / 2
    add(
        *box_of(corners, 2),
        lambda d: imaging.mu("acetal") * (cylinder_z_chord(rays.c, d, ro, h) - cylinder_z_chord(rays.c, d, rb, h)),
    )
    # the photons blurred on the fine grid, then summed over each pixel
    T = gaussian_filter(np.exp(-p), (sv * s, su * s), mode="constant", cval=1.0)
    I = T.reshape(H, s, W, s).mean((1, 3))
    N = rng.poisson(I * imaging.photons_per_px)
    raw = np.clip(np.rint(N * imaging.raw_gain), 0, imaging.full_scale).astype(np.uint16)
    log_image = -np.log(np.maximum(raw, 0.5) / (imaging.raw_gain * imaging.photons_per_px))
    return raw, log_image, -np.log(I)


def timed(fn, n):
    """(wall s, cpu s) per call over n calls."""
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(n):
        fn(k)
    return (time.perf_counter() - w0) / n, (time.process_time() - c0) / n


def main() -> None:
    features = load("ftrac_2005")
    cam = Camera()
    imaging = ImagingModel()
    clean = ImagingModel(photons_per_px=None)
    R, t = Workspace().sample(N_POSES, features.nominal_beam_direction, np.random.default_rng(2026))
    bg = anatomy(seed=1)
    for k in range(3):  # warm caches and allocator
        render(features, R[k], t[k], cam, imaging, rng=np.random.default_rng(k))

    cases = {
        "geometry only (line_integral_box)": lambda k: line_integral_box(features, R[k], t[k], cam, imaging),
        "noise-free render": lambda k: render(features, R[k], t[k], cam, clean),
        "full model (noise, raw, log)": lambda k: render(
            features, R[k], t[k], cam, imaging, rng=np.random.default_rng(k)
        ),
        "full model + anatomy background": lambda k: render(
            features, R[k], t[k], cam, imaging, rng=np.random.default_rng(k), background=bg
        ),
    }
    best = {name: (math.inf, math.inf) for name in cases}
    base = (math.inf, math.inf)
    for r in range(ROUNDS):
        line = []
        for name, fn in cases.items():
            w, c = timed(fn, N_POSES)
            best[name] = (min(best[name][0], w), min(best[name][1], c))
            line.append(f"{name.split(' (')[0]} {1e3 * w:.1f}")
        w, c = timed(
            lambda k: baseline_render(features, R[k], t[k], cam, imaging, np.random.default_rng(k)), N_BASELINE
        )
        base = (min(base[0], w), min(base[1], c))
        print(f"round {r + 1}: " + ", ".join(line) + f", baseline {1e3 * w:.0f} ms per image")

    # the two implementations draw the same image (up to the noise model): check on one pose
    ours = render(features, R[0], t[0], cam, clean).line_integral
    p0 = baseline_render(features, R[0], t[0], cam, imaging, np.random.default_rng(0))[2]
    diff = float(np.abs(ours - p0).max())

    print(f"\nradiograph simulator, ftrac_2005 + body, 1024 × 1024, {N_POSES} workspace poses, best of {ROUNDS} rounds")
    print(f"machine: {machine()} (shared with other jobs)")
    print(f"{'':36s} {'wall ms':>8s} {'cpu ms':>8s}")
    for name, (w, c) in best.items():
        print(f"{name:36s} {1e3 * w:8.1f} {1e3 * c:8.1f}")
    print(f"{'baseline (textbook, see module)':36s} {1e3 * base[0]:8.1f} {1e3 * base[1]:8.1f}   ({N_BASELINE} poses)")
    full = best["full model (noise, raw, log)"][0]
    print(
        f"\nfull model: {1e3 * full:.1f} ms per image (target ≤ 50 ms: {'met' if full <= 0.05 else 'missed'}); "
        f"{base[0] / full:.0f}× faster than the baseline"
    )
    print(f"largest |difference| of the noise-free line integral vs the baseline's: {diff:.2e}")


if __name__ == "__main__":
    main()
