"""A real headless browser (Chromium) looking at a report: screenshot and rendered DOM.

Used by the tests (the page must render, not only parse) and to make the docs'
screenshots. Chromium comes from the system packages (Debian: ``apt-get install chromium``;
``make test`` installs it when missing and the user is root).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

#: executable names tried in order
NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium executable (``$CHROMIUM`` first), or None."""
    env = os.environ.get("CHROMIUM")
    if env and shutil.which(env):
        return shutil.which(env)
    for name in NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def _run(html: Path, extra: list[str], timeout: float) -> subprocess.CompletedProcess:
    exe = find_chromium()
    if exe is None:
        raise FileNotFoundError("chromium not found (apt-get install chromium)")
    with tempfile.TemporaryDirectory(prefix="ftrac-chromium-") as profile:
        # --no-sandbox: containers and root have no user namespaces for Chromium's sandbox;
        # the page is our own file. A private profile lets parallel tests run side by side.
        args = [
            exe,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--no-first-run",
            "--disable-extensions",
            f"--user-data-dir={profile}",
            *extra,
            Path(html).resolve().as_uri(),
        ]
        return subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False)


def screenshot(html: str | Path, png: str | Path, width: int = 1280, height: int = 2400, timeout: float = 90.0) -> Path:
    """Render ``html`` in headless Chromium at ``width`` × ``height`` CSS px into ``png``."""
    png = Path(png).resolve()
    proc = _run(Path(html), [f"--screenshot={png}", f"--window-size={width},{height}"], timeout)
    if not png.is_file():
        raise RuntimeError(f"chromium wrote no screenshot (exit {proc.returncode}): {proc.stderr[-500:]}")
    return png


def dump_dom(html: str | Path, timeout: float = 90.0) -> str:
    """The DOM after Chromium has loaded and laid out ``html`` (``--dump-dom``)."""
    proc = _run(Path(html), ["--dump-dom"], timeout)
    if proc.returncode != 0 or "<html" not in proc.stdout:
        raise RuntimeError(f"chromium --dump-dom failed (exit {proc.returncode}): {proc.stderr[-500:]}")
    return proc.stdout


def readme_screenshot(
    html: str | Path, png: str | Path, width: int = 1280, height: int = 1100, out_width: int = 900, colours: int = 256
) -> Path:
    """The top of a report as a small PNG for documentation: rendered at ``width`` ×
    ``height``, scaled to ``out_width`` px and reduced to ``colours`` colours (≤ ~200 KB)."""
    from PIL import Image

    png = Path(png)
    with tempfile.TemporaryDirectory(prefix="ftrac-shot-") as tmp:
        raw = screenshot(html, Path(tmp) / "raw.png", width, height)
        im = Image.open(raw).convert("RGB")
        im = im.resize((out_width, round(im.height * out_width / im.width)), Image.LANCZOS)
        # octree keeps the small saturated badges (median cut merges them into grey)
        im = im.quantize(colours, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.FLOYDSTEINBERG)
        png.parent.mkdir(parents=True, exist_ok=True)
        im.save(png, optimize=True)
    return png


if __name__ == "__main__":  # python -m ftrac_design.report.browser REPORT.html OUT.png
    import sys

    print(readme_screenshot(sys.argv[1], sys.argv[2]))
