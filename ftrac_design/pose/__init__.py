"""Single-image 6-DOF pose of an FTRAC fiducial (paper §II.B). numpy/scipy only.

``solve_pose(features, observation) -> Pose`` and ``solve_batch(features, observations)``
are the API; :mod:`.simulate` makes synthetic images; :mod:`.problem` has the residuals
and closed-form Jacobians that :mod:`ftrac_design.analysis` shares.
"""

from .camera import Camera
from .observation import CurveObservation, Observation, observation_from_dict, read_observations
from .problem import NoiseModel, Problem, compile_problem, evaluate
from .solver import Pose, SolverOptions, refine_pose, solve_batch, solve_pose

__all__ = [
    "Camera",
    "CurveObservation",
    "NoiseModel",
    "Observation",
    "Pose",
    "Problem",
    "SolverOptions",
    "compile_problem",
    "evaluate",
    "observation_from_dict",
    "read_observations",
    "refine_pose",
    "solve_batch",
    "solve_pose",
]
