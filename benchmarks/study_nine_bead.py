"""Paper Fig. 8: the FTRAC fiducial vs a nine-bead fiducial as segmentation error grows.

ftrac_2005 against nine_bead (nine beads, no wires, same Ø30 × 50 mm envelope) over N
workspace poses (default 7,000, the paper's "over 7000") at segmentation errors 0–3 mm:

- *equal*: the same error on every feature;
- *disparity*: the paper's measured segmentation accuracy per feature type (Table V:
  ellipses 0.13 mm, lines 0.19 mm, points 0.43 mm), which the paper kept "in mind" for
  Fig. 8. We read the x-axis as the beads' error and scale the lines' and ellipses' errors
  by 0.19/0.43 and 0.13/0.43 (the paper does not say how it applied the ratio). The
  nine-bead fiducial has beads only, so its two columns are the same.

Printed: predicted median 3-D RMS translation and rotation error (the Cramér–Rao bound is
linear in the noise σ, so every curve is a straight line through 0 — the 0 mm point is
that limit, not a computation), and the segmentation error at which each curve reaches the
paper's "1 mm and 1° mark". Monte-Carlo check with the robust solver (no initial guess) at
0.25 and 1 mm, 300 images per design: equal error for both designs, and the disparity for
FTRAC (each feature kind simulated at its own error).

The paper (§IV, Fig. 8): "even with high amounts of segmentation error, the FTRAC fiducial
exhibits only a marginal loss in accuracy. On the other hand, the errors for bead-based
fiducials climbs steadily … the error quickly climbs to the 1 mm and 1° mark for the
bead-based fiducials, while it remains consistently low for the FTRAC fiducial."
Plot: docs/img/study_nine_bead.png.

Run: ``.venv/bin/python benchmarks/study_nine_bead.py [N]``
"""

from __future__ import annotations

import sys

import numpy as np
from _common import load, machine, monte_carlo, predicted, rms3, save_plot

from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_batch
from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation

ERRORS_MM = (0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0)
TABLE_V_MM = {"point": 0.43, "line": 0.19, "ellipse": 0.13}
MC_ERRORS = (0.25, 1.0)
MC_N = 300


def kind_errors(e_mm: float) -> dict[str, float]:
    """Maximum segmentation error per feature kind, beads at ``e_mm``, Table V ratios."""
    return {k: e_mm * v / TABLE_V_MM["point"] for k, v in TABLE_V_MM.items()}


def disparity(e_mm: float) -> NoiseModel:
    """Per-axis σ (uniform magnitude: e/√6) of :func:`kind_errors`."""
    e = kind_errors(e_mm)
    return NoiseModel(e["point"] / 6**0.5, e["line"] / 6**0.5, e["ellipse"] / 6**0.5)


def monte_carlo_disparity(features, n: int, e_mm: float, seed: int) -> np.ndarray:
    """Errors (k, 6: tx ty tz mm, rx ry rz deg) of ``n`` solved images whose beads, lines and
    ellipses carry their own :func:`kind_errors` (the simulator takes one error per call, so
    each kind is simulated separately at the same pose and the curves merged in)."""
    rng = np.random.default_rng(seed)
    cam = Camera()
    R, t = Workspace().sample(n, features.nominal_beam_direction, rng)
    e = kind_errors(e_mm)
    ids = {
        "point": {p.id for p in features.points},
        "line": {ln.id for ln in features.lines},
        "ellipse": {el.id for el in features.ellipses},
    }
    obs = []
    for i in range(n):
        o = simulate_observation(features, cam, R[i], t[i], e["point"], rng, include=ids["point"])
        o.lines = simulate_observation(features, cam, R[i], t[i], e["line"], rng, include=ids["line"]).lines
        o.ellipses = simulate_observation(features, cam, R[i], t[i], e["ellipse"], rng, include=ids["ellipse"]).ellipses
        obs.append(o)
    poses = solve_batch(features, obs, SolverOptions(noise=disparity(e_mm)))
    ok = np.array([p.converged for p in poses])
    Re = np.array([p.rotation if p.converged else np.eye(3) for p in poses])
    te = np.array([p.translation_mm if p.converged else np.zeros(3) for p in poses])
    dr, dt = pose_errors(Re, te, R, t)
    return np.concatenate([dt, np.degrees(dr)], 1)[ok], int((~ok).sum())


def main(n: int = 7000) -> None:
    designs = {"ftrac_2005": load("ftrac_2005"), "nine_bead": load("nine_bead")}
    print(f"machine: {machine()}")
    print(f"\npredicted median 1σ (3-D RMS) over {n} workspace poses; seg. error = the beads' maximum error")
    print(
        f"{'seg. error mm':>13s} | {'equal: FTRAC t mm':>18s} {'r °':>6s} {'9 beads t':>10s} {'r °':>6s} | "
        f"{'disparity: FTRAC t':>19s} {'r °':>6s} {'9 beads t':>10s} {'r °':>6s}"
    )
    print(
        f"{0.0:13.2f} | {0.0:18.3f} {0.0:6.3f} {0.0:10.3f} {0.0:6.3f} | {0.0:19.3f} {0.0:6.3f} {0.0:10.3f} "
        f"{0.0:6.3f}   (limit: the bound is linear in σ)"
    )
    res = {0.0: [0.0] * 8}
    for e in ERRORS_MM:
        row = []
        for noise in (NoiseModel.from_segmentation_error(e), disparity(e)):
            for f in designs.values():
                m = predicted(f, n, e, noise=noise)
                row += [float(np.median(m.translation_rms_mm)), float(np.median(m.rotation_rms_deg))]
        res[e] = row
        print(
            f"{e:13.2f} | {row[0]:18.3f} {row[1]:6.3f} {row[2]:10.3f} {row[3]:6.3f} | "
            f"{row[4]:19.3f} {row[5]:6.3f} {row[6]:10.3f} {row[7]:6.3f}"
        )
    lin = res[3.0][2] / res[0.1][2]
    print(f"linearity: nine beads' translation at 3 mm / at 0.1 mm = {lin:.2f} (exactly linear: 30.00)")
    e1 = res[1.0]
    print(
        f"\nat 1 mm: nine beads / FTRAC = × {e1[2] / e1[0]:.1f} in translation, × {e1[3] / e1[1]:.1f} in rotation "
        f"(equal error); × {e1[6] / e1[4]:.1f} and × {e1[7] / e1[5]:.1f} with the Table V disparity"
    )
    # the bound is linear in e, so the 1 mm / 1° crossing is 1 / (error per mm of segmentation error)
    print("segmentation error (beads, mm) at which the predicted median reaches the paper's 1 mm / 1° mark:")

    def cross(per_mm: float) -> str:
        e = 1.0 / per_mm
        return f"{e:5.2f} mm" + (" (beyond the range: extrapolated)" if e > ERRORS_MM[-1] else "")

    for label, col in (("FTRAC, equal", 0), ("nine beads", 2), ("FTRAC, disparity", 4)):
        print(f"  {label:17s} 1 mm at {cross(e1[col])},  1° at {cross(e1[col + 1])}")

    print(f"\nMonte-Carlo, {MC_N} images each, robust solver, no initial guess (3-D RMS; predicted medians above)")
    print(
        f"{'seg. error mm':>13s} | {'equal: FTRAC t mm':>18s} {'r °':>6s} {'9 beads t mm':>13s} {'r °':>6s} | "
        f"{'disparity: FTRAC t mm':>22s} {'r °':>6s} | {'not solved':>10s}"
    )
    mc = {}
    for e in MC_ERRORS:
        seed = int(e * 100)
        a, b1 = monte_carlo(designs["ftrac_2005"], MC_N, e, seed=seed)
        b, b2 = monte_carlo(designs["nine_bead"], MC_N, e, seed=seed)
        c, b3 = monte_carlo_disparity(designs["ftrac_2005"], MC_N, e, seed=seed)
        mc[e] = rms3(a) + rms3(b) + rms3(c)
        print(
            f"{e:13.2f} | {mc[e][0]:18.3f} {mc[e][1]:6.3f} {mc[e][2]:13.3f} {mc[e][3]:6.3f} | {mc[e][4]:22.3f} "
            f"{mc[e][5]:6.3f} | {b1 + b2 + b3:10d}"
        )

    print(
        "\npaper (Fig. 8, >7000 poses): bead errors climb quickly to the 1 mm and 1° mark; FTRAC shows only a "
        "marginal loss in accuracy even at high segmentation error."
    )
    print(
        f"ours: the beads reach 1 mm at {1.0 / e1[2]:.2f} mm and 1° at {1.0 / e1[3]:.2f} mm of segmentation "
        f"error, FTRAC (disparity) only at {1.0 / e1[4]:.2f} mm and (extrapolated) {1.0 / e1[5]:.1f} mm — the "
        f"paper's picture. "
        f"But no curve flattens: the predicted errors (and the solver's) grow in proportion to the "
        f"segmentation error for both designs; FTRAC is lower by a constant factor (× {e1[2] / e1[0]:.1f} at "
        f"equal error, × {e1[6] / e1[4]:.1f} with the disparity), not more robust in shape."
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = (0.0, *ERRORS_MM)
    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    for k, (ax, label) in enumerate(zip(axs, ("translation, mm", "rotation, deg"))):
        ax.plot(xs, [res[x][0 + k] for x in xs], "o-", color="tab:blue", label="FTRAC, equal error")
        ax.plot(xs, [res[x][4 + k] for x in xs], "o--", color="tab:blue", mfc="none", label="FTRAC, Table V disparity")
        ax.plot(xs, [res[x][2 + k] for x in xs], "o-", color="tab:red", label="nine beads")
        ax.plot(MC_ERRORS, [mc[x][0 + k] for x in MC_ERRORS], "ks", label="solver (Monte-Carlo)")
        ax.plot(MC_ERRORS, [mc[x][2 + k] for x in MC_ERRORS], "ks")
        ax.plot(MC_ERRORS, [mc[x][4 + k] for x in MC_ERRORS], "ks", mfc="none")
        ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
        ax.set_xlabel("segmentation error (beads), mm")
        ax.set_ylabel(f"median 3-D RMS {label}")
        ax.grid(True, alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.suptitle(f"Fig. 8: FTRAC vs a nine-bead fiducial in the same envelope ({n} workspace poses)", fontsize=10)
    print(f"\nplot: {save_plot(fig, 'study_nine_bead')}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7000)
