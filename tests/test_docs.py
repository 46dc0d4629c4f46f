"""The documentation: the site builds with ``mkdocs build --strict`` (a broken link or anchor,
an unknown reference, a page left out of the nav or a docstring griffe cannot read fails it);
README.md stays short and its relative links resolve; the interface contract in the
repository has the sections the code cites as "SPEC §N"; the code cites only documents that
exist; the architecture page and its picture show the layers of the import contract."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"

#: a Markdown link or image target: ``[text](target)`` / ``![alt](target "title")``
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")


def relative_links(text: str) -> list[str]:
    """Targets of the Markdown links in ``text`` that point into the repository (no scheme, no
    mail address, not a bare anchor)."""
    out = []
    for target in LINK.findall(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
            continue
        out.append(target)
    return out


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading: lower case, punctuation dropped (but ``-`` and
    ``_``), spaces as ``-``."""
    text = re.sub(r"[`*_]{1,2}(?=\S)|(?<=\S)[`*_]{1,2}", "", heading.strip()).lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def headings(md: Path) -> list[str]:
    """The ATX headings of a Markdown file, outside fenced code."""
    out, fenced = [], False
    for line in md.read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
        elif not fenced and re.match(r"#{1,6} ", line):
            out.append(line.lstrip("#").strip())
    return out


def test_readme_is_at_most_200_lines():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= 200, f"README.md has {n} lines; move the detail into docs/"


def test_every_relative_link_in_the_readme_resolves():
    links = relative_links(README.read_text(encoding="utf-8"))
    assert links, "README.md links into the docs"
    broken = []
    for target in links:
        path, _, anchor = target.partition("#")
        dest = (README.parent / path).resolve()
        if not dest.exists():
            broken.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in {github_anchor(h) for h in headings(dest)}:
            broken.append(f"{target}: no heading with that anchor")
    assert not broken, broken


def test_the_link_finder_finds_links_and_skips_urls():
    text = '[a](docs/x.md) ![p](docs/img/p.png "t") [w](https://e.org) [s](#here)'
    assert relative_links(text) == ["docs/x.md", "docs/img/p.png"]
    assert github_anchor("Design, build, `check` (CNC)") == "design-build-check-cnc"


def test_the_contract_in_the_repository_has_every_section_the_code_cites():
    spec = DOCS / "reference" / "spec.md"
    sections = {m.group(1) for h in headings(spec) if (m := re.match(r"(\d+)\. ", h))}
    assert sections == {"1", "2", "3", "4", "5"}, sections
    cited = set()
    for path in (ROOT / "ftrac_design").rglob("*.py"):
        cited |= set(re.findall(r"SPEC §\s*(\d+)", path.read_text(encoding="utf-8")))
    assert cited and cited <= sections, f"cited {sorted(cited)}, the contract has {sorted(sections)}"


def test_the_code_cites_only_documents_in_the_repository():
    missing, outside = [], []
    sources = [
        *(ROOT / "ftrac_design").rglob("*.py"),
        *(ROOT / "ftrac_design" / "presets").rglob("*.toml"),
        *(ROOT / "tests").glob("*.py"),
        *(ROOT / "benchmarks").rglob("*.py"),
    ]
    for path in sources:
        if path == Path(__file__).resolve():
            continue
        text = path.read_text(encoding="utf-8")
        for doc in re.findall(r"\b(docs/[\w/.-]+\.md)\b", text):
            if not (ROOT / doc).exists():
                missing.append(f"{path.relative_to(ROOT)}: {doc}")
        if "/work/shared" in text or "../shared/" in text:
            outside.append(str(path.relative_to(ROOT)))
    assert not missing, missing
    assert not outside, f"these cite files outside the repository: {outside}"


def named_in_docs() -> tuple[set[str], set[str]]:
    """The repository paths (``ftrac_design/…``, ``benchmarks/…``, ``tests/…``, ``docs/…``) and
    the dotted names (``ftrac_design.…``) that the pages, README.md and benchmarks/README.md
    name in code spans; placeholders (``<name>``) and globs are left out."""
    pages = [*DOCS.rglob("*.md"), README, ROOT / "benchmarks" / "README.md"]
    paths, dotted = set(), set()
    for page in pages:
        for span in re.findall(r"`([^`\n]+)`", page.read_text(encoding="utf-8")):
            if re.fullmatch(r"(ftrac_design|benchmarks|tests|docs)/[\w./-]+", span) and not span.endswith("/."):
                paths.add(span.rstrip(".,:;"))
            elif re.fullmatch(r"ftrac_design(\.\w+)+", span):
                dotted.add(span)
    return paths, dotted


def resolves(dotted: str) -> bool:
    """Whether ``dotted`` is an importable module or an attribute path from one."""
    import importlib

    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def test_the_docs_name_only_files_and_objects_that_exist():
    paths, dotted = named_in_docs()
    assert len(paths) > 50 and len(dotted) > 10, (len(paths), len(dotted))
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing, f"the docs name files that do not exist: {missing}"
    unknown = sorted(d for d in dotted if not resolves(d))
    assert not unknown, f"the docs name modules or objects that do not exist: {unknown}"


def test_the_name_checker_tells_real_from_made_up_names():
    assert resolves("ftrac_design.pose.solve_pose") and resolves("ftrac_design.design.presets")
    assert not resolves("ftrac_design.pose.no_such_solver") and not resolves("ftrac_design.no_such_room")


def contract_layers() -> list[list[str]]:
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    (layers,) = [c["layers"] for c in conf["tool"]["importlinter"]["contracts"] if c["type"] == "layers"]
    return [[room.strip() for room in layer.split("|")] for layer in layers]


def test_the_architecture_page_and_its_picture_show_the_contract_layers():
    rows = []
    for line in (DOCS / "architecture.md").read_text(encoding="utf-8").splitlines():
        m = re.match(r"\|\s*(\d+)\s*\|\s*([^|]+)\|", line)
        if m:
            rows.append((int(m.group(1)), re.findall(r"`(\w+)`", m.group(2))))
    layers = contract_layers()
    assert [r for _, r in rows] == layers, "docs/architecture.md's layers table differs from pyproject.toml"
    assert [i for i, _ in rows] == list(range(1, len(layers) + 1))
    from PIL import Image

    drawn = Image.open(DOCS / "img" / "layers.png").info.get("Description")
    assert drawn == " > ".join(" | ".join(layer) for layer in layers), (
        "docs/img/layers.png is older than the contract: run docs/gen_layers.py"
    )


def where_things_are(page: Path = DOCS / "architecture.md") -> list[tuple[str, str]]:
    """(path, what) of each row of the architecture page's "Where things are" table."""
    text = page.read_text(encoding="utf-8").split("## Where things are", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in text.splitlines():
        m = re.match(r"\|\s*`([^`]+)`\s*\|(.*)\|\s*$", line)
        if m:
            rows.append((m.group(1), m.group(2)))
    return rows


def test_the_architecture_page_names_every_room_once_and_only_its_own_files():
    rows = where_things_are()
    rooms = sorted(p.name for p in (ROOT / "ftrac_design").iterdir() if (p / "__init__.py").is_file())
    named = [path.split("/")[1] for path, _ in rows if path.startswith("ftrac_design/")]
    assert sorted(named) == rooms, f"each room once: the page has {sorted(named)}, the package {rooms}"
    wrong = []
    for path, what in rows:
        if not path.startswith("ftrac_design/"):
            continue
        for cited in re.findall(r"`([\w/]+\.py)`", what):
            # a bare module name is the room's own; a path with a folder is from the package root
            target = ROOT / "ftrac_design" / cited if "/" in cited else ROOT / path / cited
            if not target.is_file():
                wrong.append(f"{path}: {cited}")
    assert not wrong, f"the rows cite modules their room does not have: {wrong}"


def test_the_room_table_reader_reads_rows(tmp_path):
    page = tmp_path / "a.md"
    page.write_text(
        "## Where things are\n\n| path | what |\n| --- | --- |\n| `ftrac_design/x` | one (`a.py`) |\n\n## Next\n"
    )
    assert where_things_are(page) == [("ftrac_design/x", " one (`a.py`) ")]


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None, reason="mkdocs is not installed (make installs it)")
@pytest.mark.timeout(600)
def test_the_site_builds_strict_with_no_warning(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), NO_MKDOCS_2_WARNING="1")
    # not -q: mkdocs then drops warnings before --strict counts them
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "mkdocs",
            "build",
            "--strict",
            "-f",
            str(ROOT / "mkdocs.yml"),
            "-d",
            str(tmp_path / "site"),
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    log = res.stdout + res.stderr
    assert res.returncode == 0, log[-4000:]
    assert "WARNING" not in log, log[-4000:]
    for page in (
        "index.html",
        "reference/spec/index.html",
        "reference/cli/index.html",
        "api/pose/index.html",
        "benchmarks/index.html",
        "architecture/index.html",
    ):
        assert (tmp_path / "site" / page).is_file(), page
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    from ftrac_design.cli.main import COMMANDS

    assert all(f"ftrac-design {name}" in cli for name in COMMANDS), "the command line page misses a command"
    bench = (tmp_path / "site" / "benchmarks" / "index.html").read_text(encoding="utf-8")
    first = next(h for h in headings(ROOT / "benchmarks" / "README.md")[1:])
    assert re.sub(r"[`*]", "", first).split(" ")[0] in re.sub(r"<[^>]+>", "", bench)
