"""MkDocs hooks for the site (mkdocs.yml ``hooks:``).

The package's docstrings name other objects with Sphinx roles (``:func:`solve_pose```), which
mkdocstrings renders as the role's text followed by the name in code. The role's text is
dropped from the page, leaving the name in code.
"""

from __future__ import annotations

import re

#: ``:func:`` / ``:class:`` / ``:mod:`` … right before the code span the backquotes became
ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|const):(?=<code>)")


def on_page_content(html: str, **kwargs) -> str:
    """The page's HTML with Sphinx role prefixes removed before code spans."""
    return ROLE.sub("", html)
