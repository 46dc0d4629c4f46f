"""Does the solver's misfit rule (refuse κ > 3 and p < 1e-12) refuse scrambled
images without refusing good ones?

Good images: workspace poses of each preset at 0.25 and 0.05 mm segmentation error, solved
with the true camera, with the paper's C-arm calibration errors (§III.A: focal 2 mm, principal
point 0.5 mm, pixel 1 µm) and with five times those; the solver's noise model stays at its
default (0.25 mm). Scrambled images: two beads ≥ 20 px apart swapped, two wires whose images
lie ≥ 2 px apart swapped, every bead id shifted by one, or one bead moved by 100–600 px.

Run: ``.venv/bin/python benchmarks/misfit_rule.py [N] [--scrambled-only]`` (N good images per
row, default 300; N/4 scrambled images per row, each also solved with the rule off).
"""

from __future__ import annotations

import math
import sys

import numpy as np
from _common import load, machine

from ftrac_design.pose import Camera, SolverOptions, solve_batch, solve_pose
from ftrac_design.pose.simulate import PAPER_CALIBRATION_ERROR, CalibrationError, Workspace, simulate_observation

PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")
FIVE_X = CalibrationError(
    5 * PAPER_CALIBRATION_ERROR.focal_mm,
    5 * PAPER_CALIBRATION_ERROR.principal_point_mm,
    5 * PAPER_CALIBRATION_ERROR.pixel_mm,
)
CONDITIONS = [
    ("0.25 mm, calibrated", None, 0.25),
    ("0.25 mm, paper's C-arm errors", PAPER_CALIBRATION_ERROR, 0.25),
    ("0.25 mm, 5x paper's C-arm errors", FIVE_X, 0.25),
    ("0.05 mm, calibrated", None, 0.05),
    ("0.05 mm, paper's C-arm errors", PAPER_CALIBRATION_ERROR, 0.05),
]


def _line_distance(A: np.ndarray, B: np.ndarray) -> float:
    def one(P, Q):
        c = Q.mean(0)
        n = np.linalg.svd(Q - c)[2][1]
        return float(np.abs((P - c) @ n).mean())

    return 0.5 * (one(A, B) + one(B, A))


def scramble(obs, how: str, rng: np.random.Generator):
    """A scrambled copy of a simulated observation, or None when ``how`` does not apply."""
    import copy

    o = copy.deepcopy(obs)
    ids = sorted(o.points)
    if how == "swap beads":
        far = [(a, b) for i, a in enumerate(ids) for b in ids[i + 1 :] if np.hypot(*(o.points[a] - o.points[b])) > 20]
        if not far:
            return None
        a, b = far[rng.integers(len(far))]
        o.points[a], o.points[b] = o.points[b], o.points[a]
    elif how == "move bead":
        k = ids[rng.integers(len(ids))]
        ang, r = rng.uniform(0, 2 * np.pi), rng.uniform(100, 600)
        o.points[k] = o.points[k] + r * np.array([np.cos(ang), np.sin(ang)])
    elif how == "shift ids":
        vals = [o.points[k] for k in ids]
        o.points = dict(zip(ids, vals[1:] + vals[:1]))
    else:  # swap wires
        sec = o.lines
        keys = sorted(sec)
        if len(keys) < 2:
            return None
        a, b = rng.choice(len(keys), 2, replace=False)
        if _line_distance(sec[keys[a]].points, sec[keys[b]].points) < 2.0:
            return None
        sec[keys[a]], sec[keys[b]] = sec[keys[b]], sec[keys[a]]
    return o


def main(n: int = 300, scrambled_only: bool = False) -> None:
    print(f"machine: {machine()} (shared with other jobs)")
    cam = Camera()
    print(f"{'preset':11s} {'good images':34s} {'solved':>7s} {'kappa max':>9s} {'min p':>8s} {'p<1e-12':>8s}")
    for preset in PRESETS if not scrambled_only else ():
        f = load(preset)
        for label, cal, e in CONDITIONS:
            rng = np.random.default_rng(1)
            R, t = Workspace().sample(n, f.nominal_beam_direction, rng)
            obs = [
                simulate_observation(f, cam, R[i], t[i], e, rng, solve_camera=cal.draw(cam, rng) if cal else None)
                for i in range(n)
            ]
            ps = solve_batch(f, obs)
            k = np.array([p.noise_scale for p in ps])
            pv = np.array([p.residual_p_value for p in ps])
            ok = np.mean([p.converged for p in ps])
            print(
                f"{preset:11s} {label:34s} {ok:7.1%} {np.nanmax(k):9.2f} {np.nanmin(pv):8.1g} "
                f"{np.mean(pv < 1e-12):8.1%}"
            )
    print()
    print(f"{'preset':11s} {'scramble':12s} {'images':>6s} {'converged':>9s} {'without rule':>12s}  refused by")
    for preset in PRESETS:
        f = load(preset)
        for how in ("swap beads", "swap wires", "shift ids", "move bead"):
            count, conv, conv0, why = 0, 0, 0, {}
            for seed in range(n // 4):
                rng = np.random.default_rng(seed)
                R, t = Workspace().sample(1, f.nominal_beam_direction, rng)
                o = scramble(simulate_observation(f, cam, R[0], t[0], 0.25, rng), how, rng)
                if o is None:
                    continue
                p = solve_pose(f, o, SolverOptions(starts=32))
                count += 1
                conv += p.converged
                # the same image with the misfit rule off (a solver without it)
                conv0 += solve_pose(f, o, SolverOptions(starts=32, misfit_noise_scale=math.inf)).converged
                if not p.converged:
                    key = (p.error or "").split(":")[0].split("(")[0].strip()[:40]
                    why[key] = why.get(key, 0) + 1
            if count:
                top = ", ".join(f"{v} {k}" for k, v in sorted(why.items(), key=lambda x: -x[1])[:3])
                print(f"{preset:11s} {how:12s} {count:6d} {conv:9d} {conv0:12d}  {top}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 300, "--scrambled-only" in sys.argv)
