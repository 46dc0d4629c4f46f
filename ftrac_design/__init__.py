"""ftrac_design — design, manufacture and score FTRAC radiographic fiducials.

Data flows one way: ``design`` (validated parameters) → ``features`` (the geometry, the one
source of truth) → ``cad`` (CadQuery parts), ``pose`` (single-image solver) and
``analysis`` (Jacobian conditioning). ``pose`` and ``analysis`` never import CadQuery.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("ftrac_design")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
