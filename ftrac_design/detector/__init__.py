"""The learned feature detector: dense maps of where an X-ray image shows the fiducial's balls
and wires, computed once per image by a small convolutional network through ONNX Runtime.

The network reads any image a C-arm hands over (raw counts, a log image or a display frame,
either polarity) after a fixed normalisation (:mod:`.normalise`) at a working scale where a
ball is about 1.7 px in radius, and gives per output cell (2 working pixels) a ball's
probability and sub-pixel offset and a wire's probability and direction (:mod:`.decode`). It
was trained on this package's own simulator only (:mod:`ftrac_design.training`); the weights
and their model card ship in ``models/``. The detections are evidence for the geometric back
end (:mod:`ftrac_design.segment`), never a pose: the labelling, the acceptance tests and the
covariance decide. Without ONNX Runtime (the ``detect`` extra) the tracker uses its classical
detectors.
"""

from .decode import Detections, decode
from .normalise import network_input, working_scale
from .runtime import Detector, available, load_detector

__all__ = ["Detections", "Detector", "available", "decode", "load_detector", "network_input", "working_scale"]
