"""The shipped network run through ONNX Runtime on the CPU, and its model card.

``models/detector.onnx`` holds the weights and ``models/detector.json`` their card: how they were
trained (the command, its settings, the data's seeds), their figures, and the sha256 of the
ONNX file, which is checked when the network is loaded (a file that does not match its card is
not used). ONNX Runtime is the ``detect`` extra; without it :func:`available` is False and the
tracker uses its classical detectors.
"""

from __future__ import annotations

import importlib.util
import json
import threading
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, require
from ..fileio import sha256_file
from .decode import Detections, decode
from .normalise import network_input, working_scale

#: the shipped network and its card, inside the package
MODEL_FILE = "detector.onnx"
CARD_FILE = "detector.json"


def model_dir() -> Path:
    """The folder of the shipped network (``ftrac_design/detector/models``)."""
    return Path(str(resources.files("ftrac_design.detector") / "models"))


def available(path: str | Path | None = None) -> bool:
    """Whether the learned detector can run: ONNX Runtime is installed and the network (``path``,
    default the shipped one) and its card are there."""
    folder = Path(path) if path is not None else model_dir()
    return (
        importlib.util.find_spec("onnxruntime") is not None
        and (folder / MODEL_FILE).is_file()
        and (folder / CARD_FILE).is_file()
    )


@dataclass
class Detector:
    """A loaded network: call :meth:`detect` on an image.

    Attributes
    ----------
    session : onnxruntime.InferenceSession
    card : dict
        The model card (``detector.json``).
    threads : how many threads it may use: ONNX Runtime's, and with more than one the input's
        two scales side by side (:func:`.normalise.network_input`).
    """

    session: Any
    card: dict
    threads: int = 1

    def maps(self, x: np.ndarray) -> np.ndarray:
        """The network's raw output (6, h/2, w/2) for an input (2, h, w) (:func:`.network_input`)."""
        return self.session.run(None, {"image": x[None]})[0][0]

    def detect(
        self, image: np.ndarray, bead_radius_px: float, valid: np.ndarray | None = None, max_beads: int = 64
    ) -> Detections:
        """Balls and wires in ``image`` (H, W) for a design whose balls read ``bead_radius_px``
        in radius (px, at the tracker's assumed magnification); ``valid`` (H, W) bool where the
        image can be read."""
        s = working_scale(bead_radius_px)
        x = network_input(image, s, valid, side_by_side=self.threads > 1)
        return decode(self.maps(x), s, np.shape(image), max_beads)


_LOADED: dict[str, Detector] = {}
_LOCK = threading.Lock()


def load_detector(path: str | Path | None = None, threads: int = 2) -> Detector:
    """The network in ``path`` (a folder with ``detector.onnx`` and ``detector.json``; default the
    shipped one), loaded once per process and thread count.

    Raises
    ------
    MissingDependencyError
        ONNX Runtime is not installed (the ``detect`` extra).
    InputError
        The folder lacks the files, or the network's sha256 is not its card's.
    """
    ort = require("onnxruntime", "detect", "the learned feature detector")
    folder = Path(path) if path is not None else model_dir()
    key = f"{folder.resolve()}|{threads}"
    with _LOCK:
        if key in _LOADED:
            return _LOADED[key]
        onnx, card_path = folder / MODEL_FILE, folder / CARD_FILE
        for f in (onnx, card_path):
            if not f.is_file():
                raise InputError(f, None, "the learned detector's file (train one with `ftrac-design train-detector`)")
        try:
            card = json.loads(card_path.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(card_path, None, f"the detector's model card as JSON ({exc})") from None
        if card.get("sha256") != sha256_file(onnx):
            raise InputError(card_path, "sha256", f"the sha256 of {onnx.name}; the weights do not match their card")
        so = ort.SessionOptions()
        so.intra_op_num_threads = threads
        so.inter_op_num_threads = 1
        # threads that sleep between layers rather than spin: with another process on the
        # second core, spinning threads waited on each other (512² input: 2 spinning threads
        # 24 ms, one 18 ms, 2 sleeping 14 ms; quiet, 2 threads 9.8 ms either way)
        so.add_session_config_entry("session.intra_op.allow_spinning", "0")
        session = ort.InferenceSession(str(onnx), so, providers=["CPUExecutionProvider"])
        _LOADED[key] = Detector(session, card, threads)
        return _LOADED[key]
