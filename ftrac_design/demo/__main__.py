"""``python -m ftrac_design.demo`` (``make demo``): the whole chain on the presets."""

import sys

from .run import main

sys.exit(main())
