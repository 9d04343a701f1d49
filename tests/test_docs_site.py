"""The guides build as a site, their links land, and the generated module map is current.

- The site: ``mkdocs build --strict`` of ``mkdocs.yml`` into a scratch folder (what ``make docs``
  runs) succeeds; strict with every ``validation`` check at ``warn`` means a link to a missing
  page or anchor, or a page outside the nav, fails the build. Every Markdown file under docs/
  is in the nav, and every nav page is written.
- The links: every relative link of README.md, CHANGELOG.md and docs/**/*.md names an
  existing file, and a ``#fragment`` one of its headings by GitHub's anchor rule
  (:mod:`scripts.docs_links`, which the site uses too). README.md and CHANGELOG.md are not part
  of the site, so only this check covers them.
- The module map of docs/architecture.md equals what ``scripts/module_map.py`` generates.

Each check is shown failing on a planted fault in a scratch copy (the real tree is only read).
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from scripts import docs_links, module_map
from sim.paths import REPO_ROOT

MKDOCS_YML = REPO_ROOT / "mkdocs.yml"
DOCS = REPO_ROOT / "docs"
LINKED = [REPO_ROOT / "README.md", REPO_ROOT / "CHANGELOG.md", *sorted(DOCS.rglob("*.md"))]
BUILD_TIMEOUT_S = 300   # a hang bound only: the build takes about a second
needs_mkdocs = pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None,
                                  reason="mkdocs is not installed (the `dev` extra: "
                                         "`make test` installs it)")


def _build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    """``python -m mkdocs build --strict`` of ``config`` into ``site``."""
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict",
                           "-f", str(config), "-d", str(site)], cwd=config.parent,
                          capture_output=True, text=True, timeout=BUILD_TIMEOUT_S, check=False)


def _nav_pages(nav: list) -> list[str]:
    """The page paths of a nav tree (``- Title: page.md`` or ``- Title: [children]``)."""
    pages = []
    for entry in nav:
        for value in (entry.values() if isinstance(entry, dict) else [entry]):
            pages += _nav_pages(value) if isinstance(value, list) else [value]
    return pages


def _nav() -> list[str]:
    return _nav_pages(yaml.safe_load(MKDOCS_YML.read_text())["nav"])


@needs_mkdocs
def test_the_site_builds_strict_and_writes_every_page(tmp_path: Path) -> None:
    proc = _build(MKDOCS_YML, tmp_path / "site")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for page in _nav():
        html = page.removesuffix(".md") + ".html"   # use_directory_urls: false
        assert (tmp_path / "site" / html).is_file(), f"{page}: no {html}"


def test_every_page_under_docs_is_in_the_nav() -> None:
    on_disk = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")}
    nav = _nav()
    assert len(nav) == len(set(nav)), f"a page twice in the nav: {nav}"
    assert set(nav) == on_disk, (f"in docs/, not in mkdocs.yml's nav: {sorted(on_disk - set(nav))};"
                                 f" in the nav, not in docs/: {sorted(set(nav) - on_disk)}")


@needs_mkdocs
def test_a_broken_link_fails_the_site_build(tmp_path: Path) -> None:
    """On a copy of the docs: one link to a missing page, one to a missing heading."""
    shutil.copytree(DOCS, tmp_path / "docs")
    shutil.copy(MKDOCS_YML, tmp_path / "mkdocs.yml")
    shutil.copytree(REPO_ROOT / "scripts", tmp_path / "scripts")
    page = tmp_path / "docs" / "architecture.md"
    page.write_text(page.read_text() + "\n[gone](no-such-page.md) [nowhere](validation.md#no-such"
                                       "-heading)\n")
    proc = _build(tmp_path / "mkdocs.yml", tmp_path / "site")
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0, out
    assert "no-such-page.md" in out and "#no-such-heading" in out, out


@pytest.mark.parametrize("doc", LINKED, ids=[str(p.relative_to(REPO_ROOT)) for p in LINKED])
def test_every_relative_link_names_an_existing_file(doc: Path) -> None:
    problems = docs_links.broken_links(doc, check_anchors=False)
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("doc", LINKED, ids=[str(p.relative_to(REPO_ROOT)) for p in LINKED])
def test_every_link_fragment_names_a_heading(doc: Path) -> None:
    pytest.importorskip("markdown", reason="the heading check reads the Markdown with the "
                                           "`markdown` package (installed with mkdocs)")
    problems = docs_links.broken_links(doc, check_anchors=True)
    assert not problems, "\n".join(problems)


def test_the_link_check_finds_planted_broken_links(tmp_path: Path) -> None:
    """Missing file, missing heading and a good link; links in code are not links."""
    pytest.importorskip("markdown", reason="the heading check needs the `markdown` package")
    (tmp_path / "other.md").write_text("# Other\n\n## Power grasps: `dexaug generate --mode "
                                       "power`\n")
    doc = tmp_path / "doc.md"
    doc.write_text("# Doc\n\n[ok](other.md#power-grasps-dexaug-generate---mode-power) "
                   "[self](#doc) ![img](gone.png)\n[bad](other.md#power-grasps)\n"
                   "`[code](nowhere.md)`\n```\n[fenced](nowhere.md)\n```\n[web](https://x.org/y)\n"
                   "[ref]: missing/ref.md\n")
    problems = docs_links.broken_links(doc)
    assert len(problems) == 3, problems
    assert "doc.md:3: gone.png: no such file" in problems[0]
    assert "doc.md:4: other.md#power-grasps: other.md has no heading #power-grasps" in problems[1]
    assert "doc.md:10: missing/ref.md: no such file" in problems[2]


def test_anchors_follow_githubs_rule() -> None:
    assert docs_links.github_slug("Power grasps: `dexaug generate --mode power`") == (
        "power-grasps-dexaug-generate---mode-power")
    assert docs_links.github_slug("Grasps on an arm at a table: `dexaug arm` (paper §5.3)") == (
        "grasps-on-an-arm-at-a-table-dexaug-arm-paper-53")
    assert docs_links.github_slug("Measured (2-core machine, no GPU, Shadow Hand)") == (
        "measured-2-core-machine-no-gpu-shadow-hand")


def test_the_module_map_is_what_the_generator_gives() -> None:
    text = module_map.ARCHITECTURE.read_text()
    assert module_map.replace_map(text, module_map.generate()) == text, (
        "docs/architecture.md: the module map is stale; run "
        "`.venv/bin/python scripts/module_map.py --write`")
    assert text.count("| `") >= 20   # the map has its rows (one per package)


def test_a_new_package_or_docstring_changes_the_map(tmp_path: Path) -> None:
    """On a scratch tree: the map follows the docstrings, the modules and the packages."""
    pkg = tmp_path / "sim" / "widgets"
    pkg.mkdir(parents=True)
    (tmp_path / "sim" / "__init__.py").write_text('"""The bottom layer.\n\nMore."""\n')
    (pkg / "__init__.py").write_text('"""sim.widgets."""\n')
    (pkg / "gears.py").write_text("")
    first = module_map.generate(tmp_path)
    assert "| `sim/` | The bottom layer. | — |" in first
    assert f"| `sim/widgets/` | {module_map.NO_SUMMARY} | `gears` |" in first
    (pkg / "__init__.py").write_text('"""Widgets: :mod:`~sim.widgets.gears` and friends."""\n')
    (tmp_path / "augment").mkdir()
    (tmp_path / "augment" / "__init__.py").write_text('"""The augmenter."""\n')
    second = module_map.generate(tmp_path)
    assert "| `sim/widgets/` | Widgets: `sim.widgets.gears` and friends. | `gears` |" in second
    assert "| `augment/` | The augmenter. | — |" in second
    stale = module_map.replace_map(f"x\n{first}\ny\n", second)
    assert stale == f"x\n{second}\ny\n" != f"x\n{first}\ny\n"
