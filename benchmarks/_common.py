"""Shared helpers for the benchmark scripts: the machine description and preset loading."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def machine() -> str:
    """One line naming the CPU, core count, Python and numpy versions."""
    import numpy as np

    cpu = platform.processor() or "unknown CPU"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=5).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                cpu = line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}")


def load(name: str):
    """Features of preset ``models/<name>.toml``."""
    from ftrac_design.design import load_design
    from ftrac_design.features import compute_features

    return compute_features(load_design(ROOT / "models" / f"{name}.toml"))
