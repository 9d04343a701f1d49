"""Every measured-looking figure of the README and the user guides names where it comes from.

Why (issue #52): a figure typed by hand drifts from the run that made it, and a reader cannot
tell a current measurement from a lab-notebook entry of last week. A figure is a number with a
unit a measurement gives — a percentage, milliseconds, a speed-up (``×``) or a rate (``/s``,
``/min``). On a line of README.md or ``docs/*.md`` (the dated ``docs/decisions/`` notes and
CHANGELOG.md are history and keep their figures as they were measured) each such figure must
be one of:

- a rendered figure, ``<!-- fig:NAME -->…<!-- /fig -->``: its text is its record's
  (``tests/test_headline_figures.py`` checks the value);
- in a prose paragraph, or a table cell (or a part of one between "; "), that links a
  benchmark record (``benchmarks/measured/…json``, a file git keeps);
- in a table whose caption (the last prose line above it) links a record, or in a row whose
  first cell does;
- in a clause that says its other source in a comment, ``<!-- source: KIND -->`` with KIND one
  of ``paper`` (the reference paper's own figure), ``issue #N`` (a figure measured by whoever
  filed that issue, on material this repository does not hold), ``../shared/…`` (a figure a
  shared file states) or ``setting`` (a threshold or parameter the code is given, not a
  result).

Figures inside code blocks (commands, config snippets) are not prose and are not checked.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from benchmarks.figures import DOCUMENTS, MARKER, REPO_ROOT

#: a number with a unit a measurement gives (the decimal part optional; 1,000 and 1 000 alike)
FIGURE = re.compile(r"(?<![\w.])\d(?:[\d,. ]*\d)?\s?(?:%|ms\b|×|/s\b|/min\b)")
#: a link to a record file
RECORD_LINK = re.compile(r"benchmarks/measured/[\w./-]+\.json")
#: an explicit non-record source
SOURCE = re.compile(r"<!-- source: (paper|issue #\d+|\.\./shared/[\w./-]+|setting) -->")
FENCE = re.compile(r"^\s*(```|~~~)")


#: where one claim ends and the next begins in a table row: a cell or a clause after "; "
CLAUSE_BREAK = re.compile(r"\s\|(?:\s|$)|;\s")


def _cites(text: str) -> bool:
    return bool(RECORD_LINK.search(text) or SOURCE.search(text))


def _paragraphs(lines: list[str]) -> list[str]:
    """Per line, the text of the prose paragraph it belongs to (consecutive non-empty lines
    that are not table rows); "" for table rows and empty lines."""
    out, block = [""] * len(lines), []
    for i, line in enumerate([*lines, ""]):
        if line.strip() and not line.lstrip().startswith("|"):
            block.append(i)
            continue
        for j in block:
            out[j] = "\n".join(lines[k] for k in block)
        block = []
    return out


def uncited(text: str) -> list[tuple[int, str]]:
    """(line number, clause) of each figure that is neither a rendered figure nor cited
    (module docstring). Prose is cited by its paragraph (a record linked anywhere in it); a
    table row is cited cell by cell (a table cell, or a part of it between "; "), so a long
    row that cites one record cites it for that cell only; a table whose caption (the last
    prose line above it) cites a record is that record's table, every cell of it, and a row
    whose first cell cites one is that record's row."""
    lines = text.splitlines()
    paragraph = _paragraphs(lines)
    out, in_code, caption, table_cited = [], False, "", False
    for i, line in enumerate(lines):
        if FENCE.match(line):
            in_code = not in_code
            continue
        if in_code:
            continue
        is_row = line.lstrip().startswith("|")
        if is_row and not table_cited and _cites(caption):
            table_cited = True
        if not is_row:
            table_cited = False
            if line.strip():
                caption = line
        first_cell = line.strip().strip("|").split(" | ")[0] if is_row else ""
        if (is_row and (table_cited or _cites(first_cell))) or (not is_row and _cites(paragraph[i])):
            continue
        for clause in CLAUSE_BREAK.split(MARKER.sub("", line)):   # rendered figures are cited
            prose = re.sub(r"`[^`]*`", "", clause)                 # inline code is not prose
            if FIGURE.search(prose) and not _cites(clause):
                out.append((i + 1, clause.strip()))
    return out


def _kept(path: Path) -> bool:
    """Whether git keeps ``path`` (committed, or new and not ignored)."""
    return path.is_file() and subprocess.run(
        ["git", "check-ignore", "-q", str(path)], cwd=REPO_ROOT, check=False).returncode != 0


@pytest.mark.parametrize("doc", DOCUMENTS, ids=lambda p: str(p.relative_to(REPO_ROOT)))
def test_every_figure_names_its_record_or_source(doc: Path) -> None:
    bad = uncited(doc.read_text())
    assert not bad, (f"{doc.relative_to(REPO_ROOT)}: figures without a record or source "
                     f"(mark them, link their record, say <!-- source: ... -->, or move a dated "
                     f"finding to docs/decisions/):\n"
                     + "\n".join(f"  line {n}: {line[:160]}" for n, line in bad))


@pytest.mark.parametrize("doc", DOCUMENTS, ids=lambda p: str(p.relative_to(REPO_ROOT)))
def test_every_linked_record_exists(doc: Path) -> None:
    text = doc.read_text()
    missing = sorted({m for m in RECORD_LINK.findall(text) if not _kept(REPO_ROOT / m)})
    assert not missing, f"{doc.relative_to(REPO_ROOT)}: linked records git does not keep: {missing}"


def test_the_rule_catches_a_typed_figure_and_accepts_each_citation() -> None:
    """The check can fail: a typed figure is caught; each way of citing it passes."""
    assert [n for n, _ in uncited("fine\nlift-drop passes 91 % of grasps\n")] == [2]
    assert uncited("speed 335 grasps/min and 12 ms a step, 1.5× faster\n") != []
    assert uncited("<!-- fig:augment -->91 %<!-- /fig --> of them\n") == []
    assert uncited("91 % ([record](../benchmarks/measured/augment/x.json))\n") == []
    assert uncited("45 % on the pitcher <!-- source: issue #54 -->\n") == []
    assert uncited("covers ≥ 10 % of the frame <!-- source: setting -->\n") == []
    assert uncited("```\ndexaug generate --n 50 # 90 %\n```\n") == []
    assert uncited("the `--quick 10 %` flag\n") == []
    assert uncited("45 % <!-- source: my guess -->\n") != []
    # one record link covers its own clause, not the rest of a long table row
    row = "| a | 91 % ([record](../benchmarks/measured/augment/x.json)); 9.7 % nudged, no record yet |\n"
    assert [c for _, c in uncited(row)] == ["9.7 % nudged, no record yet"]
    # a record in backticks cites too; a table under a caption that cites a record is covered
    assert uncited("91 % (record `benchmarks/measured/a/b.json`)\n") == []
    table = "| object | pass |\n| --- | --- |\n| can | 94 % |\n"
    assert uncited("From [the record](../benchmarks/measured/a/b.json):\n\n" + table) == []
    assert [n for n, _ in uncited("From a run last week:\n\n" + table)] == [5]
    assert uncited("| can (`benchmarks/measured/a/b.json`) | 94 % |\n") == []
    assert uncited("| can | 94 % | `benchmarks/measured/a/b.json` |\n") != []
