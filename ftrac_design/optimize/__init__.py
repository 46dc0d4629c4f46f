"""Design optimisation under the manufacturing rules. No CadQuery import.

- :mod:`.space` — the search space: which design values vary, within what (unit cube ↔ design);
- :mod:`.evaluate` — one candidate: design rules as graded margins first, then the score;
- :mod:`.execution` — where evaluations run (in process, local processes, a Dask cluster);
- :mod:`.search` — CMA-ES / NSGA-II ask/tell, the evaluation log, resume;
- :mod:`.setup` — the design read, the space and the evaluation settings of a search;
- :mod:`.verify`, :mod:`.imagecheck`, :mod:`.tables`, :mod:`.plots` — the winner checked on fresh
  poses, by the solver and on rendered images, and shown;

A whole run as ``ftrac-design optimize`` does it (log, resume, outputs) is
:func:`ftrac_design.workflows.optimize.optimize`.
"""

from __future__ import annotations

from .evaluate import EvalSettings, evaluate_candidate
from .search import OBJECTIVES, SearchConfig, run_search
from .setup import prepare, read_design
from .space import SearchSpace, default_space, load_space, parse_space

__all__ = [
    "EvalSettings",
    "OBJECTIVES",
    "SearchConfig",
    "SearchSpace",
    "default_space",
    "evaluate_candidate",
    "load_space",
    "parse_space",
    "prepare",
    "read_design",
    "run_search",
]
