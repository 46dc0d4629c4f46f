"""The detector's network (PyTorch): a small encoder–decoder of depthwise-separable convolutions.

Input (2, h, w) at the working scale (:func:`ftrac_design.detector.network_input`), output
(6, h/2, w/2) (:data:`ftrac_design.detector.decode.CHANNELS`). A strided stem, three stages at
1/2, 1/4 and 1/8 of the working resolution (the last dilated, so that a cell sees about 80
working pixels around it: a ball among the fiducial's wires, not a seed among the anatomy's
edges), and two decoder steps that add each stage back. Depthwise-separable blocks keep it at
~40 000 weights and a few milliseconds per 512² image on two CPU cores.
"""

from __future__ import annotations

from ..errors import require

torch = require("torch", "train", "training the learned feature detector")
nn = torch.nn


def _separable(ci: int, co: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(ci, ci, 3, stride, padding=dilation, dilation=dilation, groups=ci, bias=False),
        nn.BatchNorm2d(ci),
        nn.ReLU(inplace=True),
        nn.Conv2d(ci, co, 1, bias=False),
        nn.BatchNorm2d(co),
        nn.ReLU(inplace=True),
    )


class DetectorNet(nn.Module):
    """The network; ``widths`` are the channels of the three stages."""

    def __init__(self, widths: tuple[int, int, int] = (24, 48, 72)):
        super().__init__()
        a, b, c = widths
        self.widths = widths
        self.stem = nn.Sequential(
            nn.Conv2d(2, a, 3, 2, padding=1, bias=False), nn.BatchNorm2d(a), nn.ReLU(inplace=True)
        )
        self.stage1 = nn.Sequential(_separable(a, a), _separable(a, a))
        self.down2 = _separable(a, b, stride=2)
        self.stage2 = nn.Sequential(_separable(b, b), _separable(b, b))
        self.down3 = _separable(b, c, stride=2)
        self.stage3 = nn.Sequential(_separable(c, c, dilation=2), _separable(c, c, dilation=4))
        self.lift3 = nn.Conv2d(c, b, 1)
        self.merge2 = _separable(b, b)
        self.lift2 = nn.Conv2d(b, a, 1)
        self.merge1 = nn.Sequential(_separable(a, a), _separable(a, a))
        self.head = nn.Conv2d(a, 6, 1)
        with torch.no_grad():
            # a ball or a wire is rare: start both classifiers at a probability of ~1 %
            self.head.bias.zero_()
            self.head.bias[0] = -4.6
            self.head.bias[3] = -4.6

    def forward(self, x):
        """Maps (n, 6, h/2, w/2) of inputs (n, 2, h, w); h and w multiples of 8."""
        x1 = self.stage1(self.stem(x))
        x2 = self.stage2(self.down2(x1))
        x3 = self.stage3(self.down3(x2))
        up = nn.functional.interpolate
        y2 = self.merge2(x2 + up(self.lift3(x3), scale_factor=2.0, mode="nearest"))
        y1 = self.merge1(x1 + up(self.lift2(y2), scale_factor=2.0, mode="nearest"))
        return self.head(y1)
