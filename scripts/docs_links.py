"""How the links of README.md and docs/ resolve: one set of rules for GitHub and the site.

Why: the guides are read in two places — on GitHub, and as the MkDocs site (``mkdocs.yml``,
``make docs``) — and a link written for one must work in the other. GitHub names a heading's
anchor by its own rule (lowercase, punctuation dropped, each space a hyphen: ``## Power grasps
(`--mode power`)`` → ``#power-grasps---mode-power``); Python-Markdown's default collapses runs
of hyphens, so the same link would miss on the site. :func:`on_config` is an MkDocs hook
(``hooks:`` in ``mkdocs.yml``) that gives the site GitHub's rule, and :func:`broken_links` checks
every relative link of a document against the files and the anchors that rule gives
(``tests/test_docs_site.py``).

A relative link is an inline link or image ``[text](target)`` or a reference definition
``[name]: target`` outside code blocks and code spans, whose target has no scheme (``http:``,
``mailto:``). Its path is resolved against the document's folder; a ``#fragment`` must name a
heading of the target Markdown file (or of the document itself for ``#fragment`` alone).
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: an inline link or image target: ``](target)`` or ``](target "title")``
_INLINE = re.compile(r"\]\(\s*<?(?P<target>[^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
#: a reference definition at the start of a line: ``[name]: target``
_REFERENCE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(?P<target>\S+?)>?(?:\s.*)?$")
_FENCE = re.compile(r"^\s*(```|~~~)")
_CODE_SPAN = re.compile(r"(`+).+?\1")
_SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def github_slug(value: str, separator: str = "-") -> str:
    """A heading's anchor as GitHub names it: lowercase, every character that is not a letter,
    digit, mark, space, hyphen or underscore dropped, each space a ``separator``. (The signature
    is Python-Markdown's ``toc`` ``slugify``.)"""
    kept = "".join(c for c in value.strip().lower()
                   if c.isalnum() or c in " -_" or unicodedata.category(c).startswith("M"))
    return kept.replace(" ", separator)


def on_config(config: Any) -> Any:
    """MkDocs hook: the site's heading anchors by :func:`github_slug` (the ``toc`` extension's
    ``slugify``), so the links the documents carry for GitHub land on the site too."""
    config["mdx_configs"].setdefault("toc", {})["slugify"] = github_slug
    return config


def relative_links(text: str) -> Iterator[tuple[int, str]]:
    """(line number, target) of every relative link of a Markdown text (module docstring)."""
    in_fence = False
    for k, line in enumerate(text.splitlines(), start=1):
        if _FENCE.match(line):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        bare = _CODE_SPAN.sub("", line)
        targets = [m["target"] for m in _INLINE.finditer(bare)]
        ref = _REFERENCE.match(bare)
        if ref:
            targets.append(ref["target"])
        for target in targets:
            if not _SCHEME.match(target):
                yield k, target


def anchors(text: str) -> set[str]:
    """The anchors of a Markdown text's headings, as the site and GitHub name them (needs the
    ``markdown`` package, which MkDocs installs; its ``toc`` extension finds the headings as the
    site does, with MkDocs' default extensions)."""
    import markdown

    md = markdown.Markdown(extensions=["toc", "tables", "fenced_code"],
                           extension_configs={"toc": {"slugify": github_slug}})
    md.convert(text)
    found: set[str] = set()
    stack: list[dict[str, Any]] = list(md.toc_tokens)   # type: ignore[attr-defined]
    while stack:
        token = stack.pop()
        found.add(token["id"])
        stack.extend(token["children"])
    return found


def broken_links(doc: Path, check_anchors: bool = True) -> list[str]:
    """One line per relative link of ``doc`` whose file (or, with ``check_anchors``, heading)
    does not exist: ``doc:line: target: why``."""
    text = doc.read_text()
    problems = []
    cache: dict[Path, set[str]] = {}
    for line, target in relative_links(text):
        path_part, _, fragment = target.partition("#")
        path = (doc.parent / path_part).resolve() if path_part else doc.resolve()
        if not path.exists():
            problems.append(f"{doc}:{line}: {target}: no such file {path}")
        elif check_anchors and fragment and path.suffix == ".md":
            if path not in cache:
                cache[path] = anchors(path.read_text())
            if fragment not in cache[path]:
                problems.append(f"{doc}:{line}: {target}: {path.name} has no heading "
                                f"#{fragment}")
    return problems
