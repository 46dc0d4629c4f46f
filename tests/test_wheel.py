"""The package as people install it: a wheel built from this checkout carries the preset
designs and search spaces, and, installed into a fresh virtual environment away from the
checkout, ``ftrac-design presets``, ``ftrac-design build ftrac_2005`` and ``python -m
ftrac_design.demo`` run from a temporary directory.

The fresh environment gets this environment's third-party packages (numpy, CadQuery, …)
through a ``.pth`` line naming this site-packages, so nothing is downloaded to install the
wheel; ``.pth`` files inside that folder (the editable install's finder) are not processed
there, so ``ftrac_design`` can only come from the wheel.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

from ftrac_design.design.presets import PRESETS_DIR, SPACES_DIR

ROOT = Path(__file__).resolve().parents[1]

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(importlib.util.find_spec("pip") is None, reason="pip is not installed in this environment"),
    pytest.mark.timeout(900),
]


def _offline_backend() -> bool:
    """Whether this environment holds the build backend pyproject.toml asks for (setuptools
    >= 69 and wheel), so the wheel builds without reaching a package index."""
    try:
        major = int(importlib.metadata.version("setuptools").split(".")[0])
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return False
    return major >= 69 and importlib.util.find_spec("wheel") is not None


def _run(cmd: list, cwd: Path, env: dict | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    res = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, (
        f"{' '.join(map(str, cmd))} -> {res.returncode}\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    )
    return res


def build_wheel(tmp: Path) -> Path:
    """Build the wheel of this checkout in ``tmp`` and return its path.

    The sources are copied first so that setuptools' ``build/`` and ``*.egg-info`` land in
    ``tmp``, not in the checkout.

    Parameters
    ----------
    tmp : pathlib.Path
        An empty scratch directory.

    Returns
    -------
    pathlib.Path
        The one ``ftrac_design-*.whl`` written to ``tmp/dist``.
    """
    src = tmp / "src"
    for folder in ("ftrac_design", "models"):  # the package, and the design files the build maps in
        shutil.copytree(ROOT / folder, src / folder, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    isolation = ["--no-build-isolation"] if _offline_backend() else []  # else pip fetches the backend
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", *isolation, "-w", tmp / "dist", src], tmp)
    wheels = sorted((tmp / "dist").glob("ftrac_design-*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


def fresh_venv(tmp: Path, wheel: Path) -> tuple[Path, dict]:
    """A new virtual environment in ``tmp/venv`` with ``wheel`` installed and this
    environment's installed packages visible; returns its bin folder and a clean environment
    for its commands (no PYTHONPATH pointing at the checkout)."""
    venv.EnvBuilder(with_pip=False).create(tmp / "venv")
    bindir = tmp / "venv" / "bin"
    py = bindir / "python"
    site = Path(_run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp).stdout.strip())
    (site / "ftrac_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    env.update(PATH=f"{bindir}{os.pathsep}{env.get('PATH', '')}", VIRTUAL_ENV=str(tmp / "venv"), MPLBACKEND="Agg")
    _run([sys.executable, "-m", "pip", "--python", py, "install", "-q", "--no-deps", "--no-index", wheel], tmp, env)
    where = _run([py, "-c", "import ftrac_design; print(ftrac_design.__file__)"], tmp, env).stdout.strip()
    assert Path(where).is_relative_to(site), f"ftrac_design imported from {where}, not the wheel in {site}"
    return bindir, env


def test_the_wheel_ships_the_presets_and_runs_the_demo_from_anywhere(tmp_path):
    wheel = build_wheel(tmp_path / "build")
    names = set(zipfile.ZipFile(wheel).namelist())
    presets = sorted(PRESETS_DIR.glob("*.toml"))
    spaces = sorted(SPACES_DIR.glob("*.toml"))
    assert len(presets) == 6 and len(spaces) == 6
    missing = [p.name for p in presets if f"ftrac_design/presets/{p.name}" not in names]
    missing += [f"spaces/{p.name}" for p in spaces if f"ftrac_design/presets/spaces/{p.name}" not in names]
    assert not missing, f"the wheel lacks {missing}"

    bindir, env = fresh_venv(tmp_path, wheel)
    work = tmp_path / "work"
    work.mkdir()
    listed = _run([bindir / "ftrac-design", "presets"], work, env).stdout
    assert all(p.stem in listed for p in presets + spaces), listed

    _run([bindir / "ftrac-design", "build", "ftrac_2005", "-o", work / "built"], work, env)
    assert {"fiducial.step", "fiducial.stl", "features.json", "manifest.json"} <= {
        p.name for p in (work / "built").iterdir()
    }

    demo = _run([bindir / "python", "-m", "ftrac_design.demo"], work, env, timeout=800)
    out = work / "outputs" / "ftrac_2005"
    for name in ("fiducial.step", "features.json", "analysis/analysis.json", "report.html"):
        assert (out / name).is_file(), f"{name} not written by the demo:\n{demo.stdout[-2000:]}"
