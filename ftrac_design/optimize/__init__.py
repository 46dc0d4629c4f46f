"""Design optimisation under the manufacturing rules. No CadQuery import.

- :mod:`.space` — the search space: which design values vary, within what (unit cube ↔ design);
- :mod:`.evaluate` — one candidate: design rules as graded margins first, then the score;
- :mod:`.execution` — where evaluations run (in process, local processes, a Dask cluster);
- :mod:`.search` — CMA-ES / NSGA-II ask/tell, the evaluation log, resume;
- :mod:`.report` — verification on fresh poses and by the solver, outputs;
- :mod:`.run` — :func:`optimize`, a whole run as ``ftrac-design optimize`` does it;
"""

from __future__ import annotations

from .evaluate import EvalSettings, evaluate_candidate
from .run import optimize, prepare
from .search import OBJECTIVES, SearchConfig, run_search
from .space import SearchSpace, default_space, load_space, parse_space

__all__ = ["EvalSettings", "OBJECTIVES", "SearchConfig", "SearchSpace", "default_space",
           "evaluate_candidate", "load_space", "optimize", "parse_space", "prepare", "run_search"]
