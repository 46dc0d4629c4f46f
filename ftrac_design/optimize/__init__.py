"""Design optimisation under the manufacturing rules. No CadQuery import.

- :mod:`.space` — the search space: which design values vary, within what (unit cube ↔ design);
- :mod:`.evaluate` — one candidate: design rules as graded margins first, then the score;
- :mod:`.execution` — where evaluations run (in process, local processes, a Dask cluster);
- :mod:`.search` — CMA-ES / NSGA-II ask/tell, the evaluation log, resume;
- :mod:`.report` — verification on fresh poses and by the solver, outputs;
- :mod:`.run` — :func:`optimize`, a whole run as ``ftrac-design optimize`` does it;
- :func:`demo_step` — a few-second seeded search for ``make demo``.
"""

from __future__ import annotations

from pathlib import Path

from .evaluate import EvalSettings, evaluate_candidate
from .run import optimize, prepare
from .search import OBJECTIVES, SearchConfig, run_search
from .space import SearchSpace, default_space, load_space, parse_space

__all__ = ["EvalSettings", "OBJECTIVES", "SearchConfig", "SearchSpace", "default_space", "demo_step",
           "evaluate_candidate", "load_space", "optimize", "parse_space", "prepare", "run_search"]


def demo_step(out_dir: Path) -> str:
    """A tiny seeded search (~5 s): ftrac_mini's two ellipse tilts, 12 evaluations in this
    process at 300 poses, no CAD build or solver check, 6 rendered radiographs of start and
    best tracked; returns start vs best as text."""
    from ..design.presets import preset_path
    from .run import optimize as _optimize

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    space = out_dir / "demo_space.toml"
    space.write_text('[parameters]\n"ellipses.E1.tilt_deg" = [28.0, 36.0]\n"ellipses.E2.tilt_deg" = [28.0, 36.0]\n'
                     "[search]\nsigma0 = 0.3\npopsize = 6\n", encoding="utf-8")
    doc = _optimize(preset_path("ftrac_mini"), out_dir / "optimize", space, evaluations=12, seed=0, poses=300,
                    verify_poses=2000, solver_images=0, check_images=6, build=False, progress=False, workers=0,
                    command_line="demo_step")
    s, b = doc["start"]["verification"]["predicted"], doc["best"]["verification"]["predicted"]
    p = doc["best"]["parameters"]
    i0, i1 = doc["start"]["verification"]["images"], doc["best"]["verification"]["images"]
    return (f"optimize (demo): ftrac_mini, E1/E2 tilt within 28–36°, {doc['run']['evaluations']} evaluations "
            f"(CMA-ES, seed 0, 300 search poses)\n"
            f"  start: tilts 30.0° / 30.0°, p95 translation {s['translation_p95_mm']:.3f} mm, "
            f"rotation {s['rotation_p95_deg']:.3f}° (2,000 fresh poses)\n"
            f"  best:  tilts {p['ellipses.E1.tilt_deg']:.1f}° / {p['ellipses.E2.tilt_deg']:.1f}°, "
            f"p95 translation {b['translation_p95_mm']:.3f} mm, rotation {b['rotation_p95_deg']:.3f}°\n"
            f"  rendered: 6 radiographs of each tracked with no initial guess, p95 translation "
            f"{_fmt(i0['translation_p95_mm'])} -> {_fmt(i1['translation_p95_mm'])} mm, rotation "
            f"{_fmt(i0['rotation_p95_deg'])} -> {_fmt(i1['rotation_p95_deg'])}° (right {i0['right']} / {i1['right']})\n"
            f"  -> {out_dir / 'optimize'}/")


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"
