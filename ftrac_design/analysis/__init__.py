"""Jacobian-conditioning analysis of a fiducial design. numpy/scipy only.

- :func:`analyse_poses` — per-pose conditioning and predicted (Cramér–Rao) accuracy of a
  design, of each feature group and of each feature, batched over thousands of poses;
- :func:`score_design` — the design score over the workspace with pass/fail thresholds;
- :func:`blind_spot_atlas` — the same over every view direction, with the worst directions
  and the features that go blind there;
- :func:`image_clearance` / :func:`pair_clearances` — segmentability: how far apart the
  features' images stay (px beyond their widths) and where they overlap.

The Jacobian is the pose solver's (:mod:`ftrac_design.pose.problem`), with its parameter
scaling; see :mod:`.information` for why its JᵀJ is the Fisher information.
"""

from .atlas import Atlas, blind_spot_atlas
from .information import feature_information, feature_layout, total_information, whitened_rows
from .metrics import PoseMetrics, pose_metrics
from .poses import PoseAnalysis, analyse_poses
from .score import AnalysisSettings, DesignScore, Thresholds, score_design
from .segmentability import ClearanceSettings, PairClearance, image_clearance, pair_clearances

__all__ = [
    "AnalysisSettings",
    "Atlas",
    "ClearanceSettings",
    "DesignScore",
    "PairClearance",
    "PoseAnalysis",
    "PoseMetrics",
    "Thresholds",
    "analyse_poses",
    "blind_spot_atlas",
    "feature_information",
    "feature_layout",
    "image_clearance",
    "pair_clearances",
    "pose_metrics",
    "score_design",
    "total_information",
    "whitened_rows",
]
