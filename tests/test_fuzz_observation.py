"""Fuzzing observation files (SPEC §3) through ``ftrac-design solve``, in this process:
simulated images of the presets mutated at any key (type, sign, magnitude, presence),
non-finite and huge (1e300) coordinates, duplicated beads, collinear and too-few contour
points, wrong shapes, unknown ids, degenerate conics and lines, broken camera blocks,
JSON Lines batches.

Property: exit 0, 1 or 2; exit 2 names file, key and what was expected in one to three
lines, writes nothing; exit 1 (a pose not found) still writes one SPEC §4 object per input
with ``converged: false`` and an ``error``; no traceback. Then the scrambled-image property:
features with swapped ids (beads ≥ 20 px apart, wires whose images lie ≥ 2 px apart), every
bead id shifted, or a bead moved by 100–600 px never come back ``converged: true``; swapped
wires whose images coincide are no scramble (the solver sees the same lines). Counts:
``fuzz_support.CASES``.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fuzz_support import EDGE_FLOATS, MODELS, PRESETS, assert_clean, cases, mutated, run_cli, scratch
from hypothesis import given
from hypothesis import strategies as st

from ftrac_design.design import load_design
from ftrac_design.features import compute_features, write_features
from ftrac_design.pose import Camera, SolverOptions, observation_from_dict, solve_pose
from ftrac_design.pose.simulate import Workspace, simulate_observation

CAMERA = Camera(1000.0, (0.44, 0.44), (512.0, 512.0))
_DIR = Path(tempfile.mkdtemp(prefix="ftrac-fuzz-features-"))
FEATURES = {p: compute_features(load_design(MODELS / f"{p}.toml")) for p in PRESETS}
FEATURE_FILES = {p: write_features(_DIR / f"{p}.json", f) for p, f in FEATURES.items()}


def _simulated(preset: str, seed: int, coefficients: bool = False, e_mm: float = 0.25):
    f = FEATURES[preset]
    rng = np.random.default_rng(seed)
    R, t = Workspace().sample(1, f.nominal_beam_direction, rng)
    return simulate_observation(f, CAMERA, R[0], t[0], e_mm, rng, as_coefficients=coefficients), R[0], t[0]


#: valid observations to start from: 3 poses per preset, contour points and coefficients
BASE = {(p, s, c): _simulated(p, s, c)[0].to_dict() for p in PRESETS for s in range(3) for c in (False, True)}


def _round(doc):
    """Shorter files: 3 decimals are far below the simulated noise."""
    if isinstance(doc, float):
        return round(doc, 3) if math.isfinite(doc) and abs(doc) < 1e9 else doc
    if isinstance(doc, list):
        return [_round(x) for x in doc]
    if isinstance(doc, dict):  # coefficients keep every digit (a conic's A, B, C are ~1e-6)
        return {k: v if k in ("conic", "coefficients") else _round(v) for k, v in doc.items()}
    return doc


BASE = {k: _round(v) for k, v in BASE.items()}


@st.composite
def targeted(draw, doc: dict) -> tuple[dict, list[str]]:
    """Mutations aimed at the geometry the solver relies on (beyond :func:`mutated`)."""
    doc = json.loads(json.dumps(doc))
    done = []
    for _ in range(draw(st.integers(1, 3))):
        op = draw(
            st.sampled_from(
                [
                    "huge",
                    "duplicate",
                    "collinear",
                    "few",
                    "unknown",
                    "conic",
                    "line",
                    "same_pixel",
                    "camera",
                    "drop_all_but",
                ]
            )
        )
        pts, lines, ells = doc.get("points", {}), doc.get("lines", {}), doc.get("ellipses", {})
        if op == "huge" and pts:
            k = draw(st.sampled_from(sorted(pts)))
            pts[k][draw(st.integers(0, 1))] = draw(EDGE_FLOATS)
        elif op == "duplicate" and len(pts) >= 2:
            a, b = draw(st.permutations(sorted(pts)))[:2]
            pts[b] = list(pts[a])
        elif op == "collinear":
            for sec in (lines, ells):
                for k, v in sec.items():
                    n = len(v.get("points", [])) or 12
                    slope = draw(st.sampled_from([0.0, 1.0, 1e-12, 1e12]))
                    sec[k] = {"points": [[float(i), 100.0 + slope * i] for i in range(n)]}
        elif op == "few":
            for sec in (lines, ells):
                for k, v in sec.items():
                    if "points" in v:
                        v["points"] = v["points"][: draw(st.integers(0, 6))]
        elif op == "unknown":
            sec = draw(st.sampled_from([s for s in (pts, lines, ells) if s] or [pts]))
            if sec:
                k = draw(st.sampled_from(sorted(sec)))
                sec[draw(st.sampled_from(["X9", "", k + "x", "E1", "L1", "B1"]))] = sec.pop(k)
        elif op == "conic" and ells:
            k = draw(st.sampled_from(sorted(ells)))
            ells[k] = {
                "conic": draw(
                    st.sampled_from(
                        [
                            [1, 0, 1, 0, 0, 1],  # no real points
                            [1, 0, 1, 0, 0, 0],  # a single point
                            [1, 0, 1, -1024, -1024, 524288 - 1e-9],  # a point (almost)
                            [1, 0, 0, 0, -1, 0],  # parabola
                            [1, 0, -1, 0, 0, -1],  # hyperbola
                            [0, 0, 0, 0, 0, 0],
                            [1e300, 0, 1e300, 0, 0, -1e300],
                            [1e-300, 0, 1e-300, 0, 0, -1e-300],
                            [5e-324, 0, 5e-324, 0, 0, -5e-324],
                            [1, 0, 1e-30, 0, 0, -1],  # an extremely thin ellipse
                        ]
                    )
                )
            }
        elif op == "line" and lines:
            k = draw(st.sampled_from(sorted(lines)))
            lines[k] = {
                "coefficients": draw(
                    st.sampled_from(
                        [[0, 0, 1], [0, 0, 0], [1e-300, 0, 5], [1e300, 1e300, 1e300], [1, 0, -1e300], [5e-324, 0, 0]]
                    )
                )
            }
        elif op == "same_pixel":
            for sec in (lines, ells):
                for v in sec.values():
                    if "points" in v:
                        v["points"] = [[3.0, 4.0]] * len(v["points"])
        elif op == "camera":
            cam = doc.setdefault("camera", {})
            key = draw(st.sampled_from(["focal_length_mm", "pixel_size_mm", "principal_point_px"]))
            val = draw(st.one_of(EDGE_FLOATS, st.lists(EDGE_FLOATS, min_size=0, max_size=3)))
            cam[key] = val
        elif op == "drop_all_but":
            keep = draw(st.integers(0, 3))
            for sec in (pts, lines, ells):
                for k in sorted(sec)[keep:]:
                    del sec[k]
        done.append(op)
    return doc, done


def observation_docs():
    base = st.sampled_from(sorted(BASE)).map(lambda k: (k[0], BASE[k]))
    return base.flatmap(lambda pb: st.one_of(mutated(pb[1]), targeted(pb[1])).map(lambda m: (pb[0], m[0], m[1])))


def _check_poses(run, out: Path, n: int) -> None:
    """Exit 0/1 wrote one SPEC §4 object per observation; exit 1 ↔ some converged false."""
    if run.code == 2:
        assert not out.exists(), "exit 2 left output\n" + run.describe()
        return
    assert out.exists(), run.describe()
    text = out.read_text()
    objs = [json.loads(ln) for ln in text.splitlines() if ln.strip()] if out.suffix == ".jsonl" else [json.loads(text)]
    assert len(objs) == n, run.describe()
    for o in objs:
        assert o["format"] == "ftrac-pose" and isinstance(o["converged"], bool)
        if o["converged"]:
            assert np.all(np.isfinite(o["rotation"])) and np.all(np.isfinite(o["translation_mm"]))
        else:
            assert o.get("error"), o
    assert (run.code == 1) == any(not o["converged"] for o in objs), run.describe()


@cases("observation_solve")
@given(case=observation_docs(), jsonl=st.booleans(), extra=st.integers(0, 2))
def test_fuzz_solve(case, jsonl, extra):
    preset, doc, done = case
    with scratch() as tmp:
        if jsonl:
            src = tmp / "batch.jsonl"
            # a batch: the mutated one among valid ones (and a blank line)
            lines = [json.dumps(BASE[(preset, i, False)]) for i in range(extra)] + [json.dumps(doc), ""]
            src.write_text("\n".join(lines), encoding="utf-8")
            n, out = extra + 1, tmp / "out" / "poses.jsonl"
        else:
            src = tmp / "obs.json"
            src.write_text(json.dumps(doc), encoding="utf-8")
            n, out = 1, tmp / "out" / "pose.json"
        feats = FEATURE_FILES[preset]
        run = run_cli(["solve", "--features", feats, src, "-o", out, "--starts", "16"])
        assert_clean(run, [src, feats], tmp)
        _check_poses(run, out, n)


# ----------------------------------------------------------------- scrambled observations
#: a swap of two beads counts as a scramble when their images are this far apart (px)
BEAD_SWAP_MIN_PX = 20.0
#: … of two curves, when each curve's points lie this far (mean, px) from the other curve
CURVE_SWAP_MIN_PX = 2.0


def _image_distance(A: np.ndarray, B: np.ndarray, kind: str) -> float:
    """Mean distance (px) of one contour's points from the other curve, symmetrised: from
    the other's total-least-squares line for lines (the solver sees infinite lines), from
    the other's nearest point for ellipses."""

    def one(P, Q):
        if kind == "lines":
            c = Q.mean(0)
            n = np.linalg.svd(Q - c)[2][1]
            return float(np.abs((P - c) @ n).mean())
        return float(np.linalg.norm(P[:, None] - Q[None], axis=-1).min(1).mean())

    return 0.5 * (one(A, B) + one(B, A))


def _scramble(obs: dict, how: str, rng: np.random.Generator, preset: str) -> dict | None:
    obs = json.loads(json.dumps(obs))
    pts = obs["points"]
    ids = sorted(pts)
    if how == "swap_beads":
        # two beads whose images are far enough apart that swapping them changes the image
        far = [
            (a, b)
            for i, a in enumerate(ids)
            for b in ids[i + 1 :]
            if np.hypot(*np.subtract(pts[a], pts[b])) > BEAD_SWAP_MIN_PX
        ]
        if not far:
            return None
        a, b = far[rng.integers(len(far))]
        pts[a], pts[b] = pts[b], pts[a]
    elif how == "move_bead":
        k = ids[rng.integers(len(ids))]
        ang = rng.uniform(0, 2 * np.pi)
        r = rng.uniform(100.0, 600.0)
        pts[k] = [pts[k][0] + r * math.cos(ang), pts[k][1] + r * math.sin(ang)]
    elif how == "swap_curves":
        kind = "ellipses" if obs["ellipses"] and rng.random() < 0.5 else "lines"
        sec = obs[kind]
        keys = sorted(sec)
        if len(keys) < 2:
            return None
        a, b = rng.choice(len(keys), 2, replace=False)
        A, B = np.array(sec[keys[a]]["points"]), np.array(sec[keys[b]]["points"])
        # two wires whose images coincide (lines on one image line, within the noise) can be
        # swapped without changing what the solver sees: no scramble
        if _image_distance(A, B, kind) < CURVE_SWAP_MIN_PX:
            return None
        sec[keys[a]], sec[keys[b]] = sec[keys[b]], sec[keys[a]]
    elif how == "rotate_ids":
        # every bead takes its neighbour's position: a wholly wrong correspondence
        vals = [pts[k] for k in ids]
        for k, v in zip(ids, vals[1:] + vals[:1]):
            pts[k] = v
    return obs


@cases("scrambled_solve")
@given(
    preset=st.sampled_from(PRESETS),
    seed=st.integers(0, 2**31 - 1),
    how=st.sampled_from(["swap_beads", "move_bead", "swap_curves", "rotate_ids"]),
)
def test_scrambled_features_never_converge(preset, seed, how):
    obs0, R, t = _simulated(preset, seed, e_mm=0.25)
    rng = np.random.default_rng(seed)
    scrambled = _scramble(obs0.to_dict(), how, rng, preset)
    if scrambled is None:
        return  # e.g. nine_bead has no curves to swap
    pose = solve_pose(FEATURES[preset], observation_from_dict(scrambled, "scrambled"), SolverOptions(starts=32))
    assert not pose.converged, (how, preset, seed, pose.translation_mm, pose.noise_scale, pose.error)


@pytest.mark.parametrize("preset", PRESETS)
def test_unscrambled_simulations_converge(preset):
    """The control for the test above: the same simulations, unscrambled, are solved."""
    for seed in range(3):
        obs, R, t = _simulated(preset, seed)
        assert solve_pose(FEATURES[preset], obs).converged
