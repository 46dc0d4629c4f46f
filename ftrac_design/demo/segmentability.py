"""``make demo``'s segmentability step: do the presets' features stay apart in the image?"""

from __future__ import annotations

from ..analysis.segmentability import ClearanceSettings, segmentability, segmentability_atlas
from ..pose.camera import Camera


def demo_step(out_dir, poses: int = 2000) -> str:
    """The demo's segmentability step: the three preset designs' image clearances over
    ``poses`` workspace poses, and ``segmentability_ftrac_2005.png`` in ``out_dir``
    (a few seconds). Returns the text to print."""
    from pathlib import Path

    from ..analysis.plots import plot_segmentability
    from ..analysis.sampling import workspace_poses
    from ..design import load_design
    from ..design.presets import preset_path
    from ..features import compute_features
    from ..pose.simulate import Workspace

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cam = Camera()
    lines = [
        f"Segmentability: image clearance between features over {poses} workspace poses "
        f"(px beyond their widths; overlap = beads merge, a bead on a foreign line, or wires "
        f"sharing {ClearanceSettings().stretch_px:g} px)"
    ]
    for name in ("ftrac_2005", "ftrac_mini", "nine_bead"):
        f = compute_features(load_design(preset_path(name)))
        R, t = workspace_poses(Workspace(), f.nominal_beam_direction, poses, 0)
        seg = segmentability(f, cam, R, t)
        d = seg.to_dict(n_worst=1)
        kinds = (
            ", ".join(
                f"{k} {100 * v['overlap_share']:.1f} %"
                for k, v in d["kinds"].items()
                if v["counted"] and v["overlap_share"] > 0
            )
            or "none"
        )
        w = d["worst_poses"][0] if d["worst_poses"] else None
        worst = f"; worst {w['pair']} {w['clearance_px']:.1f} px" if w else ""
        lines.append(
            f"  {name:<11} overlap at {100 * seg.overlap_share:4.1f} % of poses ({kinds}); clearance p5 "
            f"{d['clearance_px']['p5']:.2f} px{worst}"
        )
        if name == "ftrac_2005":
            atlas = segmentability_atlas(f, cam, Workspace().depth_mm, Workspace().cone_deg, 6.0)
            plot_segmentability(seg, atlas, out_dir / "segmentability_ftrac_2005.png")
    lines.append(f"  wrote {out_dir / 'segmentability_ftrac_2005.png'}")
    return "\n".join(lines)
