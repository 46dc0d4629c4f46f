"""One self-contained HTML page per design (``ftrac-design report``, ``build --report``,
``analyze --report``): render, parameters, features, design rules of both profiles, score and
atlas, bill of materials and wire cut list, output files with their sha256, versions.

:mod:`.inputs` gathers what exists (a build directory, a design, an analysis directory);
:mod:`.page` writes the HTML (pictures as data URIs, inline CSS: no network needed to view it).
No CadQuery is imported here; ``report DESIGN.toml`` builds through :mod:`ftrac_design.cad`
in the command line wrapper. Reports that run an analysis first are written by
:mod:`ftrac_design.workflows.report`.
"""

from __future__ import annotations

from .inputs import ReportInputs, collect
from .page import SECTIONS, render_html, write_report

__all__ = ["ReportInputs", "SECTIONS", "collect", "render_html", "write_report"]
