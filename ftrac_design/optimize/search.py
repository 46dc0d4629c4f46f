"""The search: ask/tell optimisers over an executor, an evaluation log, and resume.

**Objectives** (every error is the predicted 1σ 3-D RMS over the fixed search sample,
p95 over the poses, divided by the start design's value on the same sample, so the start
scores 1):

| ``objective`` | minimised | optimiser |
| --- | --- | --- |
| ``max`` (default) | max(t/t₀, r/r₀): neither translation nor rotation may get worse unnoticed | CMA-ES |
| ``sum`` | (t/t₀ + r/r₀) / 2 | CMA-ES |
| ``translation`` | t/t₀, with r/r₀ ≤ 1 as a constraint (rotation no worse than the start) | CMA-ES |
| ``rotation`` | r/r₀, with t/t₀ ≤ 1 as a constraint | CMA-ES |
| ``translation-rotation`` | (t/t₀, r/r₀) | NSGA-II |
| ``accuracy-diameter`` | (max(t/t₀, r/r₀), body outer diameter in mm) | NSGA-II |

**Constraints**: candidates that break a rule are not scored; they (and scored ones that
break the objective's own constraint, by ``objective_violation``) are told
``W + violation`` where W is the worst feasible objective value seen so far (never below
the start's), so every feasible candidate ranks above every infeasible one and infeasible
ones are ranked by how far they are from feasibility (Deb's feasibility rules). NSGA-II
gets the violation as its constraint (G = violation ≤ 0).

**Determinism**: CMA-ES (``cma``, seeded, its global-numpy random draws kept in a private
state) and NSGA-II (``pymoo``, seeded generator) see only the told values, which come
back in submission order; an evaluation depends only on the candidate and the fixed pose
sample. So one seed gives one result with any number of workers.

**Log and resume**: every evaluation is appended to a JSON Lines log as soon as its
generation's earlier evaluations are in (line 1: the run's header; then the start design;
then one line per candidate: index, generation, unit point, parameters, design hash,
rule margins, violation, figures, objectives, seed). ``resume`` replays the logged
evaluations through the same ask/tell sequence — the same seeds give the same asks, which
must match the logged ones exactly — and evaluates only what is missing, so an interrupted
run resumed ends exactly where the uninterrupted one would have. Generations are whole:
the run stops after the generation in which the evaluation count is reached.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal, get_args

import numpy as np

from ..errors import InputError, require
from .evaluate import EvalSettings, evaluate_candidate
from .space import SearchSpace, design_hash

LOG_FORMAT = "ftrac-optimize-log"
LOG_VERSION = 1
Objective = Literal["max", "sum", "translation", "rotation", "translation-rotation", "accuracy-diameter"]
OBJECTIVES: tuple[Objective, ...] = get_args(Objective)
#: objectives searched by CMA-ES (one figure) and by NSGA-II (two)
SINGLE: tuple[Objective, ...] = OBJECTIVES[:4]
MULTI: tuple[Objective, ...] = OBJECTIVES[4:]


@dataclass(frozen=True)
class SearchConfig:
    """What is searched for and how: objective, budget, seed and optimiser settings."""

    objective: Objective = "max"
    evaluations: int = 400
    seed: int = 0
    sigma0: float = 0.1
    popsize: int | None = None

    @property
    def multi(self) -> bool:
        return self.objective in MULTI

    def header(self) -> dict:
        """What a resumed run must share with the interrupted one (not the budget)."""
        d = asdict(self)
        d.pop("evaluations")
        return d


def objective_names(objective: str) -> tuple[str, ...]:
    return {
        "translation-rotation": ("translation_ratio", "rotation_ratio"),
        "accuracy-diameter": ("accuracy_ratio", "outer_diameter_mm"),
    }.get(objective, (f"{objective}_ratio",))


def objective_violation(objective: str, figures: dict, ref: dict) -> float:
    """How far a scored candidate breaks the objective's own constraint (0 = not at all):
    ``translation`` keeps the rotation error within the start's and vice versa."""
    t = figures["translation_p95_mm"] / ref["translation_p95_mm"]
    r = figures["rotation_p95_deg"] / ref["rotation_p95_deg"]
    # on images: no more confident wrong poses than the start (percentage points of its images)
    wrong = max(0.0, figures["wrong_pct"] - ref["wrong_pct"]) if "wrong_pct" in figures and "wrong_pct" in ref else 0.0
    return {"translation": max(0.0, r - 1.0), "rotation": max(0.0, t - 1.0)}.get(objective, 0.0) + wrong


def _ok(e: dict) -> bool:
    return bool(e["feasible"]) and not e.get("objective_violation")


def objective_values(objective: str, figures: dict, ref: dict) -> tuple[float, ...]:
    """The objective vector of a scored candidate (see the module doc)."""
    t = figures["translation_p95_mm"] / ref["translation_p95_mm"]
    r = figures["rotation_p95_deg"] / ref["rotation_p95_deg"]
    return {
        "max": (max(t, r),),
        "sum": ((t + r) / 2,),
        "translation": (t,),
        "rotation": (r,),
        "translation-rotation": (t, r),
        "accuracy-diameter": (max(t, r), figures["outer_diameter_mm"]),
    }[objective]


@contextlib.contextmanager
def _private_numpy_random(holder: dict):
    """Run with numpy's global random state swapped for ``holder['state']`` (cma draws from it)."""
    outer = np.random.get_state()
    if holder.get("state") is not None:
        np.random.set_state(holder["state"])
    try:
        yield
    finally:
        holder["state"] = np.random.get_state()
        np.random.set_state(outer)


#: smallest CMA-ES standard deviation along a stock-size coordinate, in bins of its choices
CHOICE_MIN_STD_BINS = 0.3


class _Cma:
    """CMA-ES (``cma``) on the unit cube, ask/tell.

    A stock-size parameter is a coordinate cut into equal bins, one per choice. Left alone,
    CMA-ES shrinks its step there like anywhere else and settles in one bin for good (the
    first parts search found its best candidate, 0.4 mm wire, at evaluation 682, then
    converged on 0.3 mm wire 0.2 worse). Its step along such a coordinate is kept at least
    :data:`CHOICE_MIN_STD_BINS` of a bin (``cma``'s ``minstd``, as its own integer handling
    does), so each generation keeps trying the neighbouring sizes (~10 % of samples from a
    bin's centre)."""

    def __init__(self, x0: np.ndarray, config: SearchConfig, choices: tuple[int, ...] = ()):
        cma = require("cma", "optimize", "the CMA-ES design search")
        self._rng: dict = {}
        opts = {
            "bounds": [0.0, 1.0],
            "seed": config.seed + 1,
            "verbose": -9,
            "verb_log": 0,
            "verb_disp": 0,
            "tolfun": 0.0,
            "tolflatfitness": 10_000,
            "tolfunhist": 0.0,
            "tolx": 1e-9,
        }
        if config.popsize:
            opts["popsize"] = config.popsize
        if any(choices):
            opts["minstd"] = [CHOICE_MIN_STD_BINS / n if n else 0.0 for n in choices] + [0.0] * (len(x0) == 1)
        # cma works in two or more dimensions: a one-parameter space gets an inert second one
        self.dim = len(x0)
        with _private_numpy_random(self._rng):
            self.es = cma.CMAEvolutionStrategy(list(x0) + [0.5] * (self.dim == 1), config.sigma0, opts)
        self.popsize = self.es.popsize
        self._asked: list = []

    def ask(self) -> list[np.ndarray]:
        with _private_numpy_random(self._rng):
            self._asked = self.es.ask()
        return [np.asarray(x[: self.dim], float) for x in self._asked]

    def tell(self, xs: list[np.ndarray], f: np.ndarray, g: np.ndarray) -> None:
        with _private_numpy_random(self._rng):
            self.es.tell(self._asked, [float(v[0]) for v in f])

    def stopped(self) -> str | None:
        stop = {k: v for k, v in self.es.stop().items() if k not in ("maxfevals", "maxiter")}
        return ", ".join(stop) if stop else None


class _Nsga2:
    """NSGA-II (``pymoo``) on the unit cube, ask/tell; the first population holds the start."""

    def __init__(self, x0: np.ndarray, config: SearchConfig):
        require("pymoo", "optimize", "the NSGA-II design search")
        from pymoo.algorithms.moo.nsga2 import NSGA2
        from pymoo.core.problem import Problem
        from pymoo.core.termination import NoTermination

        n = len(x0)
        self.popsize = config.popsize or max(16, 4 * ((n + 3) // 4) + 8)
        rng = np.random.default_rng(config.seed)
        sampling = np.vstack([x0, rng.random((self.popsize - 1, n))])
        self.problem = Problem(n_var=n, n_obj=2, n_ieq_constr=1, xl=np.zeros(n), xu=np.ones(n))
        self.algorithm = NSGA2(pop_size=self.popsize, sampling=sampling, eliminate_duplicates=True)
        self.algorithm.setup(self.problem, termination=NoTermination(), seed=config.seed, verbose=False)
        self._pop = None

    def ask(self) -> list[np.ndarray]:
        self._pop = self.algorithm.ask()
        return [np.asarray(x, float) for x in self._pop.get("X")]

    def tell(self, xs: list[np.ndarray], f: np.ndarray, g: np.ndarray) -> None:
        from pymoo.core.evaluator import Evaluator
        from pymoo.problems.static import StaticProblem

        Evaluator().eval(StaticProblem(self.problem, F=np.asarray(f, float), G=np.asarray(g, float)), self._pop)
        self.algorithm.tell(infills=self._pop)

    def stopped(self) -> str | None:
        return None


@dataclass
class SearchResult:
    """Everything the outputs need: the start, every candidate (log entries with their
    objective values), the best (or the front) and the run's facts."""

    space: SearchSpace
    config: SearchConfig
    settings: EvalSettings
    start: dict
    entries: list[dict]
    best: dict | None
    front: list[dict]
    seconds: float
    evaluated: int
    replayed: int
    executor: str = ""
    stopped: str | None = None
    history: list[float] = field(default_factory=list)
    popsize: int | None = None

    @property
    def feasible_fraction(self) -> float:
        return float(np.mean([e["feasible"] for e in self.entries])) if self.entries else 0.0


class _Interrupted(KeyboardInterrupt):
    """Raised by ``stop_after`` (tests): the run stops as if killed after that many candidates."""


def _read_log(path: Path) -> list[dict]:
    """The complete lines of a log; a torn last line (killed mid-write) is cut off the file."""
    if not path.exists():
        return []
    raw = path.read_bytes()
    entries, good = [], 0
    for line in raw.split(b"\n"):
        if not line.strip():
            good += len(line) + 1
            continue
        try:
            entries.append(json.loads(line))
        except ValueError:
            break
        good += len(line) + 1
    if good < len(raw):
        os.truncate(path, min(good, len(raw)))
    return entries


def _front_mask(f: np.ndarray) -> np.ndarray:
    require("pymoo", "optimize", "the design search's Pareto front")
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    mask = np.zeros(len(f), bool)
    if len(f):
        mask[NonDominatedSorting().do(f, only_non_dominated_front=True)] = True
    return mask


def require_search_packages(config: SearchConfig) -> None:
    """Raise :class:`~ftrac_design.errors.MissingDependencyError` before any work when the
    ``optimize`` extra that ``config``'s search needs is not installed.

    Parameters
    ----------
    config : SearchConfig
        The search to run: CMA-ES needs ``cma``; every search needs ``pymoo`` (the Pareto front).
    """
    require("pymoo", "optimize", "the design search")
    if not config.multi:
        require("cma", "optimize", "the CMA-ES design search")


def run_search(
    space: SearchSpace,
    settings: EvalSettings,
    config: SearchConfig,
    executor: Executor,
    log_path: str | Path,
    resume: bool = False,
    progress: bool = True,
    executor_name: str = "",
    stop_after: int | None = None,
    on_generation: Callable[[int], None] | None = None,
) -> SearchResult:
    """Search ``space`` (see the module doc); evaluations run on ``executor`` and are logged
    to ``log_path`` (appended; with ``resume`` the logged ones are replayed, not re-run)."""
    from tqdm import tqdm

    require_search_packages(config)
    if config.objective not in OBJECTIVES:
        raise InputError(None, None, f"one of {', '.join(OBJECTIVES)}, got {config.objective!r}", parameter="objective")
    if config.multi and len(objective_names(config.objective)) != 2:
        raise InputError(None, None, "two objectives", parameter="objective")
    t_start = time.perf_counter()
    log = _Log.open(Path(log_path), _log_header(space, settings, config), resume)
    with contextlib.closing(log.out):
        start = log.next_logged() or log.write(_start_entry(space, settings, config))
        names = objective_names(config.objective)
        x0 = space.start_unit()
        opt = (
            _Cma(x0, config, tuple(len(p.choices) if p.choices else 0 for p in space.parameters))
            if not config.multi
            else _Nsga2(x0, config)
        )
        bar = tqdm(
            total=config.evaluations, unit="eval", desc="optimize", disable=None if progress else True, leave=False
        )
        run = _Generations(space, settings, config, executor, log, start["figures"], bar, stop_after)
        try:
            stopped = run.until_done(opt, on_generation)
        finally:
            bar.close()
    best, front = run.best, []
    feas = [e for e in run.entries if e["feasible"]]
    if feas:
        front = _front_of(feas, config)
        if config.multi:  # the most accurate point of the front is the "best" design
            best = min(front, key=lambda e: (e["objectives"][names[0]], e["index"]))
    return SearchResult(
        space,
        config,
        settings,
        start,
        run.entries,
        best,
        front,
        time.perf_counter() - t_start,
        log.counts["evaluated"],
        log.counts["replayed"],
        executor_name,
        stopped,
        run.history,
        opt.popsize,
    )


def _log_header(space: SearchSpace, settings: EvalSettings, config: SearchConfig) -> dict:
    """The log's first line: what makes two runs the same run."""
    header = {
        "kind": "run",
        "format": LOG_FORMAT,
        "version": LOG_VERSION,
        "design_sha256": design_hash(space.base),
        "space": [asdict(p) for p in space.parameters],
        "config": config.header(),
        "settings": settings.to_dict(),
    }
    return json.loads(json.dumps(header))  # tuples → lists, as the log holds them


class _Log:
    """The evaluation log: the lines an interrupted run left (replayed in order), and the file
    each new evaluation is appended to."""

    def __init__(self, path: Path, logged: list[dict], out):
        self.path, self.logged, self.out = path, logged, out
        self.pos = 1  # next logged line to replay
        self.counts = {"evaluated": 0, "replayed": 0, "written": 0}

    @classmethod
    def open(cls, path: Path, header: dict, resume: bool) -> "_Log":
        logged = _read_log(path) if resume else []
        if resume and not logged:
            raise InputError(path, None, "an evaluation log to resume (none found; run without --resume)")
        if logged:
            if logged[0] != header:
                diff = next((k for k in header if logged[0].get(k) != header.get(k)), "header")
                raise InputError(
                    path, diff, "a log of this same run (design, space, objective, seed and settings); it differs here"
                )
        elif path.exists() and path.stat().st_size:
            raise InputError(path, None, "no earlier log (pass --resume to continue it, or remove it)")
        log = cls(path, logged, open(path, "a", encoding="utf-8"))
        if not logged:
            log.out.write(json.dumps(header, allow_nan=False) + "\n")
        return log

    def write(self, entry: dict) -> dict:
        self.out.write(json.dumps(entry, allow_nan=False) + "\n")
        self.out.flush()
        self.counts["written"] += 1
        return entry

    def next_logged(self) -> dict | None:
        """The next logged line to replay (None: none left)."""
        if self.pos >= len(self.logged):
            return None
        e = self.logged[self.pos]
        self.pos += 1
        self.counts["replayed"] += 1
        return e


def _start_entry(space: SearchSpace, settings: EvalSettings, config: SearchConfig) -> dict:
    """The start design: the reference of every ratio, scored even if it breaks a rule."""
    start = {
        "kind": "start",
        "index": 0,
        "seed": config.seed,
        **evaluate_candidate(space.base, settings),
        "parameters": {p.key: p.start for p in space.parameters},
    }
    if start["figures"] is None:
        from ..design.loader import parse_design
        from ..features import compute_features
        from .evaluate import candidate_figures

        d = parse_design(space.base)
        fig = candidate_figures(d, compute_features(d), settings)
        if fig is None:
            raise InputError(
                space.base.get("name"),
                None,
                "a start design that is not singular in its workspace and tracks from at least 20 of the images",
            )
        fig.update(outer_diameter_mm=float(d.body.outer_diameter), length_mm=float(d.body.length))
        start["figures"] = fig
    return start


class _Generations:
    """The search's generations: each asked of the optimiser, evaluated (or replayed from the
    log), told back, and the best so far kept."""

    def __init__(self, space, settings, config: SearchConfig, executor, log: _Log, ref: dict, bar, stop_after):
        self.space, self.settings, self.config, self.executor = space, settings, config, executor
        self.log, self.ref, self.bar, self.stop_after = log, ref, bar, stop_after
        self.names = objective_names(config.objective)
        self.worst = np.array(objective_values(config.objective, ref, ref))
        self.entries: list[dict] = []
        self.history: list[float] = []
        self.best: dict | None = None
        self.gen = 0

    def until_done(self, opt, on_generation) -> str | None:
        """Generations until the evaluations are spent or the optimiser stops; why it stopped."""
        stopped = None
        while len(self.entries) < self.config.evaluations:
            xs = opt.ask()
            batch = self.evaluate(xs)
            self.tell(opt, xs, batch)
            self.keep(batch)
            self.gen += 1
            if on_generation is not None:
                on_generation(self.gen)
            stopped = opt.stopped()
            if stopped:
                break
        return stopped

    def evaluate(self, xs) -> list[dict]:
        """One generation's entries, in order: replayed from the log, else evaluated on the executor."""
        batch: list[dict | None] = [None] * len(xs)
        futures = []
        for j, x in enumerate(xs):
            k = len(self.entries) + j + 1
            data = self.space.candidate(x)
            e = self.log.next_logged()
            if e is not None:
                if e.get("index") != k or e.get("x") != [float(v) for v in x]:
                    raise InputError(
                        self.log.path,
                        f"line {self.log.pos}",
                        "the evaluation this run asks for next (the log belongs to another run "
                        "or another version of the optimiser)",
                    )
                batch[j] = e
            else:
                futures.append((j, k, x, self.executor.submit(evaluate_candidate, data, self.settings)))
        for j, k, x, fut in futures:  # in submission order, whoever finished first
            batch[j] = self.log.write(self.entry(k, x, fut.result()))
            self.log.counts["evaluated"] += 1
            self.bar.update(1)
            if self.stop_after is not None and self.log.counts["evaluated"] >= self.stop_after:
                raise _Interrupted(f"stopped after {self.stop_after} evaluations")
        self.bar.update(len(xs) - len(futures))
        return batch

    def entry(self, k: int, x, res: dict) -> dict:
        """A new evaluation's log entry, with its objectives where it is feasible."""
        e = {
            "kind": "candidate",
            "index": k,
            "generation": self.gen,
            "seed": self.config.seed,
            "x": [float(v) for v in x],
            "parameters": self.space.values(x),
            **res,
        }
        if e["feasible"]:
            e["objectives"] = dict(zip(self.names, objective_values(self.config.objective, e["figures"], self.ref)))
            e["objective_violation"] = objective_violation(self.config.objective, e["figures"], self.ref)
        return e

    def tell(self, opt, xs, batch: list[dict]) -> None:
        """Objective values, then what is told: the worst so far plus the violation for the infeasible."""
        for e in batch:
            if _ok(e):
                self.worst = np.maximum(self.worst, list(e["objectives"].values()))
        f = np.array(
            [
                list(e["objectives"].values())
                if _ok(e)
                else self.worst + e["violation"] + e.get("objective_violation", 0.0)
                for e in batch
            ]
        )
        g = np.array([[0.0 if _ok(e) else e["violation"] + e.get("objective_violation", 0.0)] for e in batch])
        opt.tell(xs, f, g)

    def keep(self, batch: list[dict]) -> None:
        first = self.names[0]
        for e in batch:
            self.entries.append(e)
            if (
                _ok(e)
                and not self.config.multi
                and (self.best is None or e["objectives"][first] < self.best["objectives"][first])
            ):
                self.best = e
            self.history.append(self.best["objectives"][first] if self.best else math.nan)
        if self.best is not None:
            self.bar.set_postfix_str(f"best {first} {self.best['objectives'][first]:.4f}")


def _front_of(feas: list[dict], config: SearchConfig) -> list[dict]:
    """The non-dominated feasible entries: on the objectives, or for a single objective on the
    translation–rotation trade-off among everything feasible that was scored."""
    if config.multi:
        f = np.array([list(e["objectives"].values()) for e in feas])
    else:
        f = np.array([[e["figures"]["translation_p95_mm"], e["figures"]["rotation_p95_deg"]] for e in feas])
    return sorted(
        (e for e, m in zip(feas, _front_mask(f)) if m),
        key=lambda e: list(e["objectives"].values())[1] if config.multi else e["figures"]["translation_p95_mm"],
    )
