"""Shared helpers for the benchmark scripts: the machine description and preset loading."""

from __future__ import annotations

import functools
import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def machine() -> str:
    """One line naming the CPU, core count, Python and numpy versions."""
    import numpy as np

    cpu = platform.processor() or "unknown CPU"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=5).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                cpu = line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}"


def folder_digest(folder: Path) -> str:
    """The sha256 (hex) of every file under ``folder`` but compiled bytecode, each by its
    path relative to ``folder`` and its bytes, in sorted order."""
    import hashlib

    h = hashlib.sha256()
    for f in sorted(p for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
        h.update(str(f.relative_to(folder)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


@functools.cache
def code_fingerprint() -> str:
    """12 hex digits of the sha256 of the package's code and shipped data (every file under
    ``ftrac_design/`` but compiled bytecode, :func:`folder_digest`): results cached under it
    are remade when any of it changes, rather than reused from a tracker that no longer exists."""
    return folder_digest(ROOT / "ftrac_design")[:12]


def add_view_prior_argument(ap, also: bool = False) -> None:
    """``--view-prior-deg OFF WITHIN`` on the argument parser ``ap``: each image tracked with its
    view known beforehand (:func:`view_prior`); ``also``: besides the default options' run."""
    ap.add_argument(
        "--view-prior-deg",
        type=float,
        nargs=2,
        default=None,
        metavar=("OFF", "WITHIN"),
        help=("also track" if also else "track")
        + " each image with its view known beforehand (`track --expect-view`): the true rotation "
        "turned OFF degrees about a random axis, admitting WITHIN degrees",
    )


def view_prior(R, off_deg: float, within_deg: float, seed: int, k: int):
    """A view as a user would know it beforehand (:class:`ftrac_design.segment.ViewPrior`): the
    true rotation ``R`` turned by ``off_deg`` about an axis drawn at random (seeded by the seed
    and image index ``k``), admitting ``within_deg``."""
    import math

    import numpy as np

    from ftrac_design.pose import so3
    from ftrac_design.segment import ViewPrior

    axis = np.random.default_rng([seed, k, 17]).normal(size=3)
    turn = so3.exp(axis / np.linalg.norm(axis) * math.radians(off_deg))
    return ViewPrior(turn @ np.asarray(R, float), math.radians(within_deg))


def load(name: str):
    """Features of the preset ``name`` (``models/<name>.toml``)."""
    from ftrac_design.design import load_design
    from ftrac_design.features import compute_features

    return compute_features(load_design(name))


def monte_carlo(features, n: int, e_mm: float, seed: int = 0, calibration=None, noise=None, workspace=None):
    """Solve ``n`` simulated workspace images of ``features`` (robust solver, no initial
    guess) at segmentation error ``e_mm``; with ``calibration`` (a ``CalibrationError``) each
    image is solved with a miscalibrated camera. Returns (errors (k, 6): tx ty tz mm, rx ry rz
    deg for the k solved images, number not solved)."""
    import numpy as np

    from ftrac_design.pose import Camera, NoiseModel, SolverOptions, solve_batch
    from ftrac_design.pose.simulate import Workspace, pose_errors, simulate_observation

    rng = np.random.default_rng(seed)
    cam = Camera()
    R, t = (workspace or Workspace()).sample(n, features.nominal_beam_direction, rng)
    obs = []
    for i in range(n):
        solve_cam = calibration.draw(cam, rng) if calibration is not None else None
        obs.append(simulate_observation(features, cam, R[i], t[i], e_mm, rng, solve_camera=solve_cam))
    opts = SolverOptions(noise=noise or NoiseModel.from_segmentation_error(max(e_mm, 0.1)))
    poses = solve_batch(features, obs, opts)
    ok = np.array([p.converged for p in poses])
    Re = np.array([p.rotation if p.converged else np.eye(3) for p in poses])
    te = np.array([p.translation_mm if p.converged else np.zeros(3) for p in poses])
    dr, dt = pose_errors(Re, te, R, t)
    return np.concatenate([dt, np.degrees(dr)], 1)[ok], int((~ok).sum())


def monte_carlo_pair(features, n: int, e_mm: float, seed: int, workspace=None):
    """3-D RMS (translation mm, rotation deg) of ``n`` solved images with segmentation error
    only and with the paper's C-arm errors added, and how many images were not solved."""
    from ftrac_design.pose.simulate import PAPER_CALIBRATION_ERROR

    seg, bad1 = monte_carlo(features, n, e_mm, seed=seed, workspace=workspace)
    cal, bad2 = monte_carlo(features, n, e_mm, seed=seed, workspace=workspace, calibration=PAPER_CALIBRATION_ERROR)
    return rms3(seg), rms3(cal), bad1 + bad2


def rms3(errors):
    """3-D RMS translation (mm) and rotation (deg) of Monte-Carlo errors (k, 6)."""
    import numpy as np

    return (
        float(np.sqrt(np.mean(np.sum(errors[:, :3] ** 2, 1)))),
        float(np.sqrt(np.mean(np.sum(errors[:, 3:] ** 2, 1)))),
    )


def predicted(features, n: int, e_mm: float, seed: int = 0, noise=None, workspace=None):
    """Analysis metrics (PoseMetrics) of ``features`` at ``n`` workspace poses."""
    from ftrac_design.analysis import analyse_poses
    from ftrac_design.analysis.sampling import workspace_poses
    from ftrac_design.pose import Camera, NoiseModel
    from ftrac_design.pose.simulate import Workspace

    R, t = workspace_poses(workspace or Workspace(), features.nominal_beam_direction, n, seed)
    return analyse_poses(
        features, R, t, Camera(), noise or NoiseModel.from_segmentation_error(e_mm), detail=False
    ).overall


def save_plot(fig, name: str) -> str:
    """Write ``docs/img/<name>.png`` (the docs show it) and return its path."""
    import matplotlib.pyplot as plt

    path = ROOT / "docs" / "img" / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return str(path.relative_to(ROOT))


def finish_condition_bars(fig, axes, conds: list[str], title: str, path: Path, ncol: int) -> Path:
    """Finish a figure of per-preset panels of horizontal bars, one bar per condition (bar ``y``
    of each panel is ``conds[y]``): the conditions top to bottom on the shared y axis (turned
    once: panels that share it turn together), the legend of the first panel above it in
    ``ncol`` columns, the ``title``; written to ``path`` (PNG) and returned."""
    import matplotlib.pyplot as plt

    axes[0].invert_yaxis()
    axes[0].set_yticks(range(len(conds)), conds, fontsize=8)
    axes[0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.06), ncol=ncol, fontsize=7, frameon=False)
    fig.suptitle(title, y=1.0, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path
