"""ftrac_design — design, manufacture and score FTRAC radiographic fiducials, and track a
C-arm's pose from X-ray images of one.

The rooms (sub-packages) import one way, from ``demo`` and ``cli`` at the top down to
``design``, ``fileio``, ``errors`` and ``presets`` (the layers contract in pyproject.toml,
drawn in ``docs/architecture.md``). ``pose``, ``analysis`` and everything but ``cad`` never
import CadQuery. "SPEC §N" in the docstrings is section N of the interface contract,
``docs/reference/spec.md``.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("ftrac_design")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
