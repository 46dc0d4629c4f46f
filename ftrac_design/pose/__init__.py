"""Single-image 6-DOF pose of an FTRAC fiducial (paper §II.B). numpy/scipy only.

``solve_pose(features, observation) -> Pose`` and ``solve_batch(features, observations)``
are the API; :mod:`.simulate` makes synthetic images; :mod:`.problem` has the residuals
and closed-form Jacobians that :mod:`ftrac_design.analysis` shares; :mod:`.record` is the
record of a tracked pose (:class:`TrackedPose`) and the ``pose.json`` format every writer and
reader uses.
"""

from .camera import Camera
from .observation import CurveObservation, Observation, observation_from_dict, read_observations
from .problem import NoiseModel, Problem, compile_problem, evaluate
from .record import Diagnostics, Pose, Provenance, Status, Timing, TrackedPose, read_tracked_poses
from .solver import SolverOptions, refine_pose, solve_batch, solve_pose

__all__ = [
    "Camera",
    "CurveObservation",
    "Diagnostics",
    "NoiseModel",
    "Observation",
    "Pose",
    "Problem",
    "Provenance",
    "SolverOptions",
    "Status",
    "Timing",
    "TrackedPose",
    "compile_problem",
    "evaluate",
    "observation_from_dict",
    "read_observations",
    "read_tracked_poses",
    "refine_pose",
    "solve_batch",
    "solve_pose",
]
