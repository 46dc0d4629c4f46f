"""``make demo``'s design-search step: a tiny seeded search and its rendered-image check."""

from __future__ import annotations

from pathlib import Path


def demo_step(out_dir: Path) -> str:
    """A tiny seeded search (~5 s): ftrac_mini's two ellipse tilts, 12 evaluations in this
    process at 300 poses, no CAD build or solver check, 6 rendered radiographs of start and
    best tracked; returns start vs best as text."""
    from ..design.presets import preset_path
    from ..workflows.optimize import optimize as _optimize

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    space = out_dir / "demo_space.toml"
    space.write_text(
        '[parameters]\n"ellipses.E1.tilt_deg" = [28.0, 36.0]\n"ellipses.E2.tilt_deg" = [28.0, 36.0]\n'
        "[search]\nsigma0 = 0.3\npopsize = 6\n",
        encoding="utf-8",
    )
    doc = _optimize(
        preset_path("ftrac_mini"),
        out_dir / "optimize",
        space,
        evaluations=12,
        seed=0,
        poses=300,
        verify_poses=2000,
        solver_images=0,
        check_images=6,
        build=False,
        progress=False,
        workers=0,
        command_line="demo_step",
    )
    s, b = doc["start"]["verification"]["predicted"], doc["best"]["verification"]["predicted"]
    p = doc["best"]["parameters"]
    i0, i1 = doc["start"]["verification"]["images"], doc["best"]["verification"]["images"]
    return (
        f"optimize (demo): ftrac_mini, E1/E2 tilt within 28–36°, {doc['run']['evaluations']} evaluations "
        f"(CMA-ES, seed 0, 300 search poses)\n"
        f"  start: tilts 30.0° / 30.0°, p95 translation {s['translation_p95_mm']:.3f} mm, "
        f"rotation {s['rotation_p95_deg']:.3f}° (2,000 fresh poses)\n"
        f"  best:  tilts {p['ellipses.E1.tilt_deg']:.1f}° / {p['ellipses.E2.tilt_deg']:.1f}°, "
        f"p95 translation {b['translation_p95_mm']:.3f} mm, rotation {b['rotation_p95_deg']:.3f}°\n"
        f"  rendered: 6 radiographs of each tracked with no initial guess, p95 translation "
        f"{_fmt(i0['translation_p95_mm'])} -> {_fmt(i1['translation_p95_mm'])} mm, rotation "
        f"{_fmt(i0['rotation_p95_deg'])} -> {_fmt(i1['rotation_p95_deg'])}° (right {i0['right']} / {i1['right']})\n"
        f"  -> {out_dir / 'optimize'}/"
    )


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"
