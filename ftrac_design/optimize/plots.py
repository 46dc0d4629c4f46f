"""The optimiser's pictures: the best objective so far and the feasible share per generation
(``convergence.png``), and the Pareto front of a multi-objective run (``pareto.png``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..fileio import atomic_file
from .search import SearchResult, _ok, objective_names


def _save(fig, plt, path: Path) -> None:
    """Lay ``fig`` out, write it to ``path`` atomically (PNG, 110 dpi) and close it."""
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def plot_convergence(res: SearchResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = objective_names(res.config.objective)
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    idx = np.arange(1, len(res.entries) + 1)
    vals = np.array([e["objectives"][names[0]] if _ok(e) else np.nan for e in res.entries])
    ax[0].plot(idx, vals, ".", ms=3, color="0.6", label="feasible candidate")
    best = np.fmin.accumulate(np.where(np.isnan(vals), np.inf, vals))
    if names[0].endswith("ratio"):  # the start scores 1 by construction
        best = np.minimum(best, 1.0)
    ax[0].plot(idx, np.where(np.isfinite(best), best, np.nan), "C0-", label="best so far")
    ax[0].axhline(1.0 if names[0].endswith("ratio") else np.nan, color="k", lw=0.8, ls=":", label="start")
    ax[0].set_xlabel("evaluation")
    ax[0].set_ylabel(names[0].replace("_", " "))
    lo, hi = np.nanpercentile(vals, [0, 90]) if np.isfinite(vals).any() else (0, 1)
    ax[0].set_ylim(min(lo, 1.0) * 0.97, max(hi, 1.0) * 1.03)
    ax[0].legend(fontsize=8)
    gens = np.array([e["generation"] for e in res.entries])
    feas = np.array([e["feasible"] for e in res.entries], float)
    ug = np.unique(gens)
    ax[1].plot(ug, [feas[gens == g].mean() for g in ug], "C1-")
    ax[1].set_xlabel("generation")
    ax[1].set_ylabel("feasible share of candidates")
    ax[1].set_ylim(0, 1.02)
    fig.suptitle(
        f"{res.start.get('name', '')} optimize --objective {res.config.objective} "
        f"(seed {res.config.seed}, {len(res.entries)} evaluations)",
        fontsize=10,
    )
    _save(fig, plt, path)


def plot_front(res: SearchResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    feas = [e for e in res.entries if e["feasible"]]
    size = res.config.objective == "accuracy-diameter"
    if size:  # accuracy against size, each error on its own panel, with plain 1/size scaling
        panels = [
            ("outer_diameter_mm", "translation_p95_mm", "p95 translation error, mm"),
            ("outer_diameter_mm", "rotation_p95_deg", "p95 rotation error, °"),
        ]
    else:
        panels = [("translation_p95_mm", "rotation_p95_deg", "p95 rotation error, °")]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.4 * len(panels), 4.2), squeeze=False)
    for ax, (kx, ky, label) in zip(axes[0], panels):
        ax.plot(
            [e["figures"][kx] for e in feas],
            [e["figures"][ky] for e in feas],
            ".",
            color="0.75",
            ms=3,
            label="feasible candidates",
        )
        ax.plot(
            [e["figures"][kx] for e in res.front],
            [e["figures"][ky] for e in res.front],
            "C0o-",
            ms=3,
            label="Pareto front",
        )
        s0 = res.start["figures"]
        ax.plot([s0[kx]], [s0[ky]], "k*", ms=10, label="start")
        if size:
            d = np.linspace(s0[kx], max(e["figures"][kx] for e in feas), 50)
            ax.plot(d, s0[ky] * s0[kx] / d, "k:", lw=1, label="start scaled up (∝ 1/size)")
            ax.set_yscale("log")
            ax.set_xlabel("body outer diameter, mm (length 2 × diameter)")
        else:
            ax.set_xlabel("p95 translation error, mm")
        if res.best is not None:
            ax.plot([res.best["figures"][kx]], [res.best["figures"][ky]], "C3*", ms=10, label="best")
        ax.set_ylabel(label + " (predicted 1σ)")
        ax.legend(fontsize=8)
    fig.suptitle(
        f"optimize --objective {res.config.objective} (seed {res.config.seed}, {len(res.entries)} evaluations)",
        fontsize=10,
    )
    _save(fig, plt, path)


def replot(log_path: str | Path, out_dir: str | Path) -> list[Path]:
    """Redraw ``convergence.png`` and ``pareto.png`` into ``out_dir`` from an evaluation log
    alone (``python -c "from ftrac_design.optimize.plots import replot; replot(LOG, DIR)"``)."""
    from .search import SearchConfig, _front_mask

    lines = [json.loads(s) for s in Path(log_path).read_text(encoding="utf-8").splitlines() if s.strip()]
    head, start = lines[0], lines[1]
    cfg = SearchConfig(**{k: v for k, v in head["config"].items() if k in SearchConfig.__dataclass_fields__})
    entries = [e for e in lines[2:] if e.get("kind") == "candidate"]
    feas = [e for e in entries if e["feasible"]]
    if cfg.multi:
        f = np.array([list(e["objectives"].values()) for e in feas])
        front = sorted((e for e, m in zip(feas, _front_mask(f)) if m), key=lambda e: list(e["objectives"].values())[1])
        best = min(front, key=lambda e: list(e["objectives"].values())[0]) if front else None
    else:
        f = np.array([[e["figures"]["translation_p95_mm"], e["figures"]["rotation_p95_deg"]] for e in feas])
        front = sorted((e for e, m in zip(feas, _front_mask(f)) if m), key=lambda e: e["figures"]["translation_p95_mm"])
        ok = [e for e in feas if _ok(e)]
        best = min(ok, key=lambda e: (list(e["objectives"].values())[0], e["index"])) if ok else None
    res = SearchResult(None, cfg, None, start, entries, best, front, 0.0, 0, len(entries))
    out = Path(out_dir)
    plot_convergence(res, out / "convergence.png")
    plot_front(res, out / "pareto.png")
    return [out / "convergence.png", out / "pareto.png"]
