"""Charts of the analysis (matplotlib, off-screen Agg): the score, the atlas, comparisons.

Every function writes one PNG and returns its path; matplotlib is imported on first use so
the analysis itself stays numpy-only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .atlas import BLIND_FACTOR, Atlas
from .score import DesignScore


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only: no display is needed or opened)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: Path) -> Path:
    """Write ``fig`` to ``path`` (PNG at 110 dpi, tight box), close it and return the path."""
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return path


def _log_x(ax) -> None:
    from matplotlib.ticker import NullFormatter

    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())  # minor labels collide on short decades
    ax.grid(True, which="both", alpha=0.3)


def _colorbar(fig, pc, ax, label: str, pad: float) -> None:
    from matplotlib.ticker import MaxNLocator

    cb = fig.colorbar(pc, ax=ax, orientation="horizontal", fraction=0.05, pad=pad)
    cb.locator = MaxNLocator(5)
    cb.update_ticks()
    cb.set_label(label, fontsize=9)


def _cdf(ax, values: np.ndarray, label: str, **kw) -> None:
    v = np.sort(values[np.isfinite(values)])
    ax.plot(v, np.arange(1, v.size + 1) / v.size, label=label, **kw)


def plot_score(score: DesignScore, path: str | Path) -> Path:
    """Distribution of the predicted errors over the workspace, with the thresholds, and
    what losing each feature would cost (95th percentile with / without it)."""
    plt = pyplot()
    pa, m, th = score.analysis, score.analysis.overall, score.thresholds
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.2))
    ax = axs[0]
    _cdf(ax, m.translation_rms_mm, "3-D RMS", color="k")
    for i, (axis, c) in enumerate(zip("xyz", ("tab:blue", "tab:orange", "tab:green"))):
        _cdf(ax, m.translation_std_mm[:, i], f"{axis} (camera)", color=c, lw=1)
    ax.axvline(th.max_translation_mm, color="r", ls="--", label="threshold (worst case)")
    ax.set_xlabel("predicted 1σ translation error, mm")
    ax.set_ylabel("fraction of workspace poses")
    _log_x(ax)
    ax.legend(fontsize=8)
    ax = axs[1]
    _cdf(ax, m.rotation_rms_deg, "3-D RMS", color="k")
    for i, (axis, c) in enumerate(zip("xyz", ("tab:blue", "tab:orange", "tab:green"))):
        _cdf(ax, np.degrees(m.rotation_std_rad[:, i]), f"about {axis}", color=c, lw=1)
    ax.axvline(th.max_rotation_deg, color="r", ls="--", label="threshold (worst case)")
    ax.set_xlabel("predicted 1σ rotation error, deg")
    _log_x(ax)
    ax.legend(fontsize=8)
    ax = axs[2]
    ids = list(pa.layout.ids)
    tl = [f["without"]["translation_loss"] or np.nan for f in score.per_feature]
    rl = [f["without"]["rotation_loss"] or np.nan for f in score.per_feature]
    x = np.arange(len(ids))
    ax.bar(x - 0.2, tl, 0.4, label="translation")
    ax.bar(x + 0.2, rl, 0.4, label="rotation")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x, ids, rotation=60, fontsize=8)
    ax.set_ylabel("p95 error without the feature / with it")
    ax.set_title("cost of losing one feature", fontsize=10)
    ax.legend(fontsize=8)
    s = score.settings
    fig.suptitle(
        f"{score.name}: {s.poses} workspace poses (cone {s.workspace.cone_deg:g}°, depth "
        f"{s.workspace.depth_mm:g} ± {s.workspace.depth_range_mm:g} mm), segmentation error "
        f"{s.segmentation_error_mm:g} mm — {'PASS' if score.passed else 'FAIL'}",
        fontsize=11,
    )
    return save_figure(fig, path)


def plot_atlas_sphere(atlas: Atlas, path: str | Path) -> Path:
    """Whole-sphere maps (Mollweide; longitude about the fiducial axis, latitude toward +z)
    of the predicted translation error and the condition number, with the workspace cone,
    each curve feature's blind band and the worst directions."""
    plt = pyplot()
    m = atlas.sphere.overall
    lon, lat = np.radians(atlas.lon), np.radians(atlas.lat)
    rel = atlas.relative_rank_ratio()
    fig = plt.figure(figsize=(15, 5))
    panels = [
        (atlas.grid(m.translation_rms_mm), "predicted 1σ translation error, mm", "viridis"),
        (atlas.grid(np.log10(m.condition)), "log10 condition number (scaled Jacobian)", "magma"),
    ]
    nb = atlas.nominal_beam / np.linalg.norm(atlas.nominal_beam)
    # the cone boundary, traced as directions at cone_deg from the nominal beam
    from ..pose.simulate import cone_directions

    ring = cone_directions(nb, np.radians(atlas.cone_deg), np.linspace(0, 2 * np.pi, 181))
    for k, (val, title, cmap) in enumerate(panels):
        ax = fig.add_subplot(1, 2, k + 1, projection="mollweide")
        pc = ax.pcolormesh(lon, lat, np.where(np.isfinite(val), val, np.nan), cmap=cmap, shading="nearest")
        _colorbar(fig, pc, ax, title, 0.08)
        for f, fid in enumerate(atlas.sphere.layout.ids):
            if atlas.sphere.layout.kinds[f] == "point" or not (rel[..., f] < BLIND_FACTOR).any():
                continue
            cs = ax.contour(lon, lat, rel[..., f], levels=[BLIND_FACTOR], colors="w", linewidths=0.8)
            ax.clabel(cs, fmt={BLIND_FACTOR: fid}, fontsize=7)
        rlon = np.arctan2(ring[:, 1], ring[:, 0])
        rlat = np.arcsin(np.clip(ring[:, 2], -1, 1))
        cut = np.flatnonzero(np.abs(np.diff(rlon)) > np.pi) + 1
        for seg_lon, seg_lat in zip(np.split(rlon, cut), np.split(rlat, cut)):
            ax.plot(seg_lon, seg_lat, color="r", lw=1.2)
        ax.plot(np.arctan2(nb[1], nb[0]), np.arcsin(nb[2]), "r+", ms=10)
        for i, w in enumerate(atlas.worst):
            ax.plot(np.radians(w["lon_deg"]), np.radians(w["lat_deg"]), "wo", ms=6, mec="k")
            ax.annotate(
                str(i + 1),
                (np.radians(w["lon_deg"]), np.radians(w["lat_deg"])),
                color="w",
                fontsize=8,
                xytext=(4, 4),
                textcoords="offset points",
            )
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
    fig.suptitle(
        f"{atlas.name}: every view direction (fiducial at the isocentre); red: the "
        f"{atlas.cone_deg:g}° workspace around the nominal beam (+); white curves: where a "
        f"feature goes blind; numbered: worst directions",
        fontsize=10,
    )
    return save_figure(fig, path)


def plot_atlas_cone(atlas: Atlas, path: str | Path) -> Path:
    """Polar maps of the workspace cone: radius = angle from the nominal beam (deg), angle =
    azimuth (0 toward the fiducial's +z)."""
    plt = pyplot()
    m = atlas.cone.overall
    th = np.radians(atlas.azimuth)
    fig = plt.figure(figsize=(12, 5))
    panels = [
        (atlas.cone_grid(m.translation_rms_mm), "predicted 1σ translation error, mm", "viridis"),
        (atlas.cone_grid(m.rotation_rms_deg), "predicted 1σ rotation error, deg", "cividis"),
        (atlas.cone_grid(m.condition), "condition number", "magma"),
    ]
    for k, (val, title, cmap) in enumerate(panels):
        ax = fig.add_subplot(1, 3, k + 1, projection="polar")
        pc = ax.pcolormesh(th, atlas.polar, val, cmap=cmap, shading="nearest")
        ax.set_theta_zero_location("N")
        ax.set_rlim(0, atlas.cone_deg)
        ax.tick_params(labelsize=7)
        _colorbar(fig, pc, ax, title, 0.1)
    fig.suptitle(
        f"{atlas.name}: the {atlas.cone_deg:g}° workspace (radius: degrees from the nominal beam; "
        f"up: tilted toward the fiducial's +z)",
        fontsize=10,
    )
    return save_figure(fig, path)


def plot_compare(scores: list[DesignScore], path: str | Path) -> Path:
    """Overlaid distributions of predicted translation and rotation errors of several designs,
    and of their smallest image clearance between features where it was measured."""
    plt = pyplot()
    seg = [s for s in scores if s.segmentability is not None]
    fig, axs = plt.subplots(1, 3 if seg else 2, figsize=(16.5 if seg else 11, 4))
    for s in scores:
        m = s.analysis.overall
        _cdf(axs[0], m.translation_rms_mm, s.name)
        _cdf(axs[1], m.rotation_rms_deg, s.name)
    axs[0].set_xlabel("predicted 1σ translation error (3-D RMS), mm")
    axs[1].set_xlabel("predicted 1σ rotation error (3-D RMS), deg")
    axs[0].set_ylabel("fraction of workspace poses")
    for ax in axs[:2]:
        _log_x(ax)
        ax.legend(fontsize=8)
    if seg:
        ax = axs[2]
        for s in seg:
            _cdf(ax, s.segmentability.clearance_px, f"{s.name} ({100 * s.segmentability.overlap_share:.1f} % overlap)")
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel("smallest image clearance between features, px (< 0: overlap)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("predicted accuracy over each design's workspace", fontsize=11)
    return save_figure(fig, path)


def plot_segmentability(seg, seg_atlas, path: str | Path, thresholds=None) -> Path:
    """Image clearance between features (px beyond their widths; negative = overlap): its
    distribution over the workspace poses, overall and per pair kind, and the smallest
    clearance over every view direction (Mollweide) and over the workspace cone (polar),
    with the overlap boundary.

    Parameters
    ----------
    seg : Segmentability
        The clearances over the workspace poses (:class:`~.segmentability.Segmentability`).
    seg_atlas : SegmentabilityAtlas
        The smallest clearance per view direction (:class:`~.segmentability.SegmentabilityAtlas`).
    path : str or pathlib.Path
        The PNG to write.
    thresholds : Thresholds or None
        Draws ``min_clearance_px`` where it is set.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    from matplotlib.colors import TwoSlopeNorm

    plt = pyplot()
    fig = plt.figure(figsize=(16, 4.8))
    _clearance_cdfs(fig.add_subplot(1, 3, 1), seg, thresholds)
    sph, cone = seg_atlas.sphere_grid(), seg_atlas.cone_grid()
    vals = np.concatenate([sph[np.isfinite(sph)], cone[np.isfinite(cone)]])
    vmin = min(-1.0, float(vals.min())) if vals.size else -1.0
    vmax = max(1.0, min(20.0, float(np.percentile(vals, 95)))) if vals.size else 1.0
    norm = TwoSlopeNorm(vcenter=0.0, vmin=vmin, vmax=vmax)
    _clearance_sphere(fig, fig.add_subplot(1, 3, 2, projection="mollweide"), seg_atlas, sph, norm)
    ax = fig.add_subplot(1, 3, 3, projection="polar")
    pcm = ax.pcolormesh(
        np.radians(seg_atlas.azimuth),
        seg_atlas.polar,
        np.clip(cone, vmin, vmax),
        cmap="RdYlBu",
        norm=norm,
        shading="nearest",
    )
    if (cone < 0).any() and (cone > 0).any():
        ax.contour(np.radians(seg_atlas.azimuth), seg_atlas.polar, cone, levels=[0.0], colors="k", linewidths=0.6)
    ax.set_theta_zero_location("N")
    ax.set_rlim(0, seg_atlas.cone_deg)
    ax.tick_params(labelsize=7)
    _colorbar(fig, pcm, ax, "smallest clearance, px", 0.1)
    ax.set_title("the workspace cone\n(radius: ° from nominal; up: tilted toward +z)", fontsize=10, pad=14)
    fig.suptitle(
        f"{seg.name}: image clearance between features at the isocentre (maps) and over the workspace "
        f"(left); stretch {seg.settings.stretch_px:g} px for wire pairs",
        fontsize=11,
        y=1.07,
    )
    return save_figure(fig, path)


def _clearance_cdfs(ax, seg, thresholds) -> None:
    """The clearances' distributions over the workspace poses: the smallest counted and each pair kind's."""
    from .segmentability import PAIR_KINDS

    pc = seg.pairs
    m = seg.clearance_px
    colours = dict(zip(PAIR_KINDS, ("tab:red", "tab:orange", "tab:gray", "tab:blue", "tab:green", "tab:purple")))
    finite = m[np.isfinite(m)]
    if finite.size:
        _cdf(ax, m, "smallest counted", color="k", lw=2)
    for k in PAIR_KINDS:
        if k in pc.kinds:
            _cdf(
                ax,
                pc.kind_minimum(k),
                k + ("" if k in pc.counted else " (not counted)"),
                color=colours[k],
                lw=1,
                ls="-" if k in pc.counted else ":",
            )
    ax.axvline(0.0, color="k", lw=0.8)
    if thresholds is not None and thresholds.min_clearance_px is not None:
        ax.axvline(thresholds.min_clearance_px, color="r", ls="--", label="threshold (p5)")
    allv = pc.clearance_px[np.isfinite(pc.clearance_px)]
    lo = allv.min() if allv.size else -1.0
    ax.set_xlim(min(lo, -1.0) - 0.5, 25.0)
    ax.set_xlabel("image clearance beyond the features' widths, px (< 0: overlap)")
    ax.set_ylabel("fraction of workspace poses")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.set_title(f"overlap at {100 * seg.overlap_share:.1f} % of {m.size} workspace poses", fontsize=10)


def _clearance_sphere(fig, ax, seg_atlas, sph: np.ndarray, norm) -> None:
    """The smallest clearance over every view direction, with the workspace cone's rim."""
    from ..pose.simulate import cone_directions

    lon, lat = np.radians(seg_atlas.lon), np.radians(seg_atlas.lat)
    pcm = ax.pcolormesh(lon, lat, np.clip(sph, norm.vmin, norm.vmax), cmap="RdYlBu", norm=norm, shading="nearest")
    if (sph < 0).any() and (sph > 0).any():
        ax.contour(lon, lat, sph, levels=[0.0], colors="k", linewidths=0.6)
    nb = seg_atlas.nominal_beam / np.linalg.norm(seg_atlas.nominal_beam)
    ring = cone_directions(nb, np.radians(seg_atlas.cone_deg), np.linspace(0, 2 * np.pi, 181))
    rlon = np.arctan2(ring[:, 1], ring[:, 0])
    rlat = np.arcsin(np.clip(ring[:, 2], -1, 1))
    cut = np.flatnonzero(np.abs(np.diff(rlon)) > np.pi) + 1
    for seg_lon, seg_lat in zip(np.split(rlon, cut), np.split(rlat, cut)):
        ax.plot(seg_lon, seg_lat, color="m", lw=1.2)
    ax.plot(np.arctan2(nb[1], nb[0]), np.arcsin(nb[2]), "m+", ms=10)
    ax.grid(True, alpha=0.3)
    ax.tick_params(labelsize=7)
    _colorbar(fig, pcm, ax, "smallest clearance, px (black: 0)", 0.08)
    ax.set_title("every view direction (magenta: the workspace cone)", fontsize=10)
