"""Every marked figure of README.md and docs/*.md is what its benchmark record gives.

A figure is marked ``<!-- fig:NAME -->…<!-- /fig -->`` and specified in
``benchmarks/headline.toml`` (its run or pinned record, the record fields it reads, its format;
:mod:`benchmarks.figures`). Here nothing is run: the committed records are read, each figure is
computed as ``benchmarks/headline.py render`` computes it, and the documents must say exactly
that. A figure edited by hand fails (shown on a temporary copy, once per figure), and so does a
spec whose record or field is missing, a marker with no spec and a spec no document shows.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest

from benchmarks.figures import (
    DOCUMENTS,
    MEASURED_DIR,
    REPO_ROOT,
    Figure,
    FigureError,
    Headline,
    Run,
    all_figure_texts,
    differences,
    evaluate,
    figure_text,
    load_headline,
    marked,
    record_of,
    render_text,
)

HEADLINE = load_headline()
TEXTS = all_figure_texts(HEADLINE)
DOC_TEXT = {str(p.relative_to(REPO_ROOT)): p.read_text() for p in DOCUMENTS}
#: (document, figure) of every marker
PLACES = [(doc, name) for doc, text in DOC_TEXT.items() for _, name, _ in marked(text)]


@pytest.mark.parametrize("doc", sorted(DOC_TEXT))
def test_every_marked_figure_equals_its_record(doc: str) -> None:
    diffs = differences(DOC_TEXT[doc], TEXTS)
    assert not diffs, (f"{doc}: figures differ from their records (run `.venv/bin/python "
                       f"benchmarks/headline.py render`):\n" + "\n".join(diffs))
    assert render_text(DOC_TEXT[doc], TEXTS) == DOC_TEXT[doc]


def test_every_spec_is_shown_and_every_marker_has_a_spec() -> None:
    shown = {name for _, name in PLACES}
    assert len(shown) >= 10, shown   # the parser still sees the markers
    assert shown == set(HEADLINE.figures), (
        f"in headline.toml, in no document: {sorted(set(HEADLINE.figures) - shown)}; "
        f"in a document, not in headline.toml: {sorted(shown - set(HEADLINE.figures))}")


def _tracked_or_addable(path: Path) -> bool:
    """Whether git keeps ``path``: committed, or not ignored (a new record awaiting its commit)."""
    ignored = subprocess.run(["git", "check-ignore", "-q", str(path)], cwd=REPO_ROOT,
                             check=False).returncode == 0
    return not ignored


@pytest.mark.parametrize("name", sorted(HEADLINE.figures))
def test_each_figure_reads_a_kept_record_that_has_its_fields(name: str) -> None:
    fig = HEADLINE.figures[name]
    path = record_of(fig, HEADLINE)
    assert path.is_file() and path.resolve().is_relative_to(MEASURED_DIR.resolve()), path
    assert _tracked_or_addable(path), f"{path} is ignored by git: not a committed record"
    record = json.loads(path.read_text())
    for key in ("benchmark", "created_utc", "command", "code", "machine", "rows"):
        assert key in record, f"{path}: not a benchmarks/record.py record (no {key!r})"
    for value, expr in fig.values.items():
        evaluate(expr, record)   # raises FigureError on a missing field
        assert value in fig.format, f"{name}: value {value!r} is not in its format"
    if fig.run is not None:   # the newest full run, not just any record of the benchmark
        run = HEADLINE.runs[fig.run]
        assert record["benchmark"] == run.benchmark
        assert run.where, f"run {run.name}: no `where` to tell a full run's record"


@pytest.mark.parametrize("doc,name", sorted(set(PLACES)), ids=[f"{d}:{n}" for d, n in sorted(set(PLACES))])
def test_a_figure_edited_by_hand_fails(doc: str, name: str, tmp_path: Path) -> None:
    """On a copy of the document: change one digit of the figure (or add one) and the check
    reports exactly that figure."""
    text = DOC_TEXT[doc]
    want = TEXTS[name]
    m = next(re.finditer(rf"<!-- fig:{name} -->(.*?)<!-- /fig -->", text))
    digit = re.search(r"\d", want)
    wrong = (want[:digit.start()] + str((int(digit[0]) + 1) % 10) + want[digit.end():]
             if digit else want + " 1")
    copy = tmp_path / Path(doc).name
    copy.write_text(text[:m.start(1)] + wrong + text[m.end(1):])
    diffs = differences(copy.read_text(), TEXTS)
    assert len(diffs) == 1 and f"fig:{name} reads {wrong!r}" in diffs[0], diffs
    assert render_text(copy.read_text(), TEXTS) == text   # render puts the record's back


def test_the_newest_matching_record_wins_and_a_missing_field_is_an_error(tmp_path: Path) -> None:
    """Record choice and field errors on a scratch measured folder (records written here)."""
    folder = tmp_path / "demo_bench"
    folder.mkdir()

    def put(stem: str, seeds: int, lifted: int) -> None:
        (folder / f"{stem}.json").write_text(json.dumps(
            {"created_utc": "2026-12-07T00:00:00+00:00", "config": {"seeds": seeds},
             "summary": {"lifted": lifted, "episodes": 10}, "rows": [{"ok": True}, {"ok": False}]}))

    put("20261207T000000Z-a", 2, 3)
    put("20261207T000100Z-b", 2, 4)
    put("20261207T000200Z-c", 1, 9)   # newest, but a small run: not a full run's record
    run = Run("r", "demo_bench", command=(), quick=(), where={"config/seeds": 2})
    fig = Figure("f", "{p:.0f} % ({k} of {n})", {"p": "100 * 'summary/lifted' / 'summary/episodes'",
                                                 "k": "count('rows/*/ok')", "n": "len('rows/*/ok')"},
                 run="r")
    h = Headline({"r": run}, {"f": fig})
    assert record_of(fig, h, tmp_path).name == "20261207T000100Z-b.json"
    assert figure_text(fig, record_of(fig, h, tmp_path)) == "40 % (1 of 2)"
    assert record_of(fig, h, tmp_path, use_where=False).name == "20261207T000200Z-c.json"
    with pytest.raises(FigureError, match="no field"):
        figure_text(Figure("g", "{x}", {"x": "summary/held"}, run="r"), folder / "20261207T000000Z-a.json")
    with pytest.raises(FigureError, match="not a value expression"):
        evaluate("__import__('os')", {})
    with pytest.raises(FigureError, match="has no entry"):
        render_text("a <!-- fig:nobody -->1<!-- /fig --> b", {})
    with pytest.raises(FigureError, match="open and close"):
        list(marked("a <!-- fig:f -->1\n<!-- /fig -->"))
