"""The detector's training set: crops of seeded scenes, their inputs and their target maps.

Scene ``k`` of a set with seed ``S`` is :func:`.scenes.make_scene` of ``S · 1 000 003 + k``, so a set is
the same on any machine and with any number of worker processes, and two sets with different
seeds share no scene. Each scene gives ``crops`` crops of ``crop`` × ``crop`` working pixels:
all but one around the fiducial's balls (the crop's centre within 40 working px of their
mean), the last anywhere in the window (most of those show anatomy only).
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..detector.normalise import STRIDE, network_input, working_scale
from ..errors import InputError
from .scenes import make_scene
from .targets import target_maps

SEED_STRIDE = 1_000_003


@dataclass
class DataSet:
    """Crops for training or validation.

    Attributes
    ----------
    x : (n, 2, c, c) float16
        Network inputs.
    y : (n, 6, c/2, c/2) float16
        Targets (:mod:`.targets`).
    offset_mask, direction_mask : (n, c/2, c/2) uint8
        Where the ball offsets and the wire directions are learned.
    condition, design : (n,) str arrays
        What each crop's scene was.
    """

    x: np.ndarray
    y: np.ndarray
    offset_mask: np.ndarray
    direction_mask: np.ndarray
    condition: np.ndarray
    design: np.ndarray

    def __len__(self) -> int:
        return len(self.x)

    def save(self, path) -> None:
        """Write to an ``.npz`` file."""
        np.savez_compressed(path, **self.__dict__)

    @classmethod
    def load(cls, path) -> "DataSet":
        """Read what :meth:`save` wrote."""
        with np.load(path, allow_pickle=False) as z:
            return cls(**{k: z[k] for k in cls.__dataclass_fields__})


def scene_crops(index: int, seed: int, crop: int = 128, crops: int = 3) -> dict[str, np.ndarray]:
    """The crops of scene ``index`` of the set with ``seed`` (arrays as :class:`DataSet`'s)."""
    sc = None
    for attempt in range(8):
        try:
            sc = make_scene(seed * SEED_STRIDE + index + attempt * 7919 * SEED_STRIDE)
            break
        except (ValueError, ArithmeticError, InputError):
            # a draw the simulator cannot render (a photon count beyond what a Poisson draw
            # takes, a pose it refuses): the scene is drawn again from a seed derived from this one
            continue
    if sc is None:
        raise RuntimeError(f"scene {index} of seed {seed}: eight draws could not be rendered")
    s = working_scale(sc.bead_radius_px)
    x = network_input(sc.image, s, sc.valid)
    h, w = x.shape[1] // STRIDE, x.shape[2] // STRIDE
    y, wt = target_maps(sc.beads_uv, sc.curves, sc.valid, s, (h, w))
    rng = np.random.default_rng([seed, index, 99])
    H, W = x.shape[1:]
    if len(sc.beads_uv):
        centre = ((sc.beads_uv.mean(0) - (s - 1) / 2) / s)[::-1]
    else:
        centre = np.array([H / 2, W / 2])
    out: dict[str, list] = {k: [] for k in ("x", "y", "offset_mask", "direction_mask")}
    for k in range(crops):
        if k < crops - 1:
            c = centre + rng.uniform(-40, 40, 2)
        else:
            c = rng.uniform(crop / 2, [H - crop / 2, W - crop / 2])
        r0 = int(np.clip(round((c[0] - crop / 2) / 2) * 2, 0, max(H - crop, 0)))
        c0 = int(np.clip(round((c[1] - crop / 2) / 2) * 2, 0, max(W - crop, 0)))
        q0, p0, q = r0 // STRIDE, c0 // STRIDE, crop // STRIDE
        out["x"].append(x[:, r0 : r0 + crop, c0 : c0 + crop])
        out["y"].append(y[:, q0 : q0 + q, p0 : p0 + q])
        out["offset_mask"].append(wt[1, q0 : q0 + q, p0 : p0 + q])
        out["direction_mask"].append(wt[4, q0 : q0 + q, p0 : p0 + q])
    return {
        "x": np.stack(out["x"]).astype(np.float16),
        "y": np.stack(out["y"]).astype(np.float16),
        "offset_mask": np.stack(out["offset_mask"]).astype(np.uint8),
        "direction_mask": np.stack(out["direction_mask"]).astype(np.uint8),
        "condition": np.array([sc.condition] * crops),
        "design": np.array([sc.design] * crops),
    }


def _job(args: tuple[int, int, int, int]) -> dict[str, np.ndarray]:
    return scene_crops(*args)


def build_dataset(scenes: int, seed: int, workers: int = 1, crop: int = 128, crops: int = 3, progress=None) -> DataSet:
    """A :class:`DataSet` of ``scenes`` scenes with ``seed`` (see the module), made by ``workers``
    processes; ``progress`` (e.g. a tqdm bar) is updated once per scene. The result does not
    depend on ``workers``."""
    jobs = [(k, seed, crop, crops) for k in range(scenes)]
    parts: list[dict[str, np.ndarray]] = []
    if workers > 1:
        with ProcessPoolExecutor(workers) as ex:
            for part in ex.map(_job, jobs, chunksize=4):
                parts.append(part)
                if progress is not None:
                    progress.update(1)
    else:
        for job in jobs:
            parts.append(_job(job))
            if progress is not None:
                progress.update(1)
    return DataSet(**{k: np.concatenate([p[k] for p in parts]) for k in DataSet.__dataclass_fields__})
