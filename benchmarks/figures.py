"""The headline figures as data: which record each figure of the README and docs/ comes from,
how it is computed from the record, and where it is written (:func:`render_text`).

Why: a figure typed by hand drifts from the run that made it (issue #52: every README number
was typed). Here a figure is a spec in ``benchmarks/headline.toml`` — a *run* (a benchmark
command and the record fields that say a record is a full run of it) or a pinned record file,
named values computed from the record by small expressions, and a ``str.format`` template — and
its place in a document is a marker pair on one line::

    <!-- fig:dgb_agreement_range -->97.0–98.7 %<!-- /fig -->

:func:`render_text` rewrites what stands between the markers; ``tests/test_headline_figures.py``
fails when a document's text differs from it. The markers are HTML comments, invisible on the
rendered page, and may enclose several cells of one table row.

Value expressions: a bare record path (``summary/lifted``), or an expression in which a quoted
string is a record path (``100 * 'summary/lifted' / 'summary/episodes'``; ``/`` separates keys,
so keys may hold dots; an integer indexes a list; ``*`` takes every key or element and skips the
missing and null ones), combined with numbers, ``+ - * /``, unary minus, and ``min``, ``max``,
``sum``, ``len``, ``mean``, ``count`` (number of true values). Every template also gets
``record`` (the record's path from the repository root) and ``date`` (its UTC date).
"""

from __future__ import annotations

import ast
import json
import re
import tomllib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from benchmarks.record import MEASURED_DIR

REPO_ROOT = Path(__file__).resolve().parents[1]
HEADLINE_TOML = Path(__file__).resolve().parent / "headline.toml"
#: the documents whose figures are rendered: the front door and its guides (as the snippet test)
DOCUMENTS = (REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md")))
#: one marked figure: its name and its text, on one line
MARKER = re.compile(r"<!-- fig:(?P<name>[a-z0-9_]+) -->(?P<text>.*?)<!-- /fig -->")
_OPEN = re.compile(r"<!-- fig:")
_CLOSE = "<!-- /fig -->"


class FigureError(ValueError):
    """A figure that cannot be computed: no record, a missing field, a bad spec or marker."""


@dataclass(frozen=True)
class Run:
    """One benchmark invocation behind figures: ``benchmark`` is its record folder, ``command``
    the script and arguments of the full run (from the repository root), ``quick`` a CI-size
    one, ``where`` the record fields (path → value) that make a record a full run of it."""

    name: str
    benchmark: str
    command: tuple[str, ...]
    quick: tuple[str, ...]
    where: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Figure:
    """One figure: from the newest record of ``run`` (or the pinned ``record``, a path under
    ``benchmarks/measured/``), ``values`` (name → expression), written as ``format``."""

    name: str
    format: str
    values: Mapping[str, str]
    run: str | None = None
    record: str | None = None


@dataclass(frozen=True)
class Headline:
    runs: Mapping[str, Run]
    figures: Mapping[str, Figure]


def load_headline(path: Path = HEADLINE_TOML) -> Headline:
    """The runs and figures of ``headline.toml``, checked for shape (each figure names exactly
    one of a known run or a pinned record)."""
    doc = tomllib.loads(path.read_text())
    runs = {name: Run(name, str(r["benchmark"]), tuple(r["command"]), tuple(r["quick"]),
                      dict(r.get("where", {})))
            for name, r in doc.get("runs", {}).items()}
    figures = {}
    for name, f in doc.get("figures", {}).items():
        fig = Figure(name, str(f["format"]), dict(f.get("values", {})), f.get("run"),
                     f.get("record"))
        if (fig.run is None) == (fig.record is None):
            raise FigureError(f"figure {name}: name exactly one of run = … or record = …")
        if fig.run is not None and fig.run not in runs:
            raise FigureError(f"figure {name}: unknown run {fig.run!r}")
        figures[name] = fig
    return Headline(runs, figures)


# -- record paths and expressions ---------------------------------------------------------------

_MISSING = object()


def lookup(record: Any, path: str) -> Any:
    """The value at ``path`` in ``record`` (see the module docstring); a path with ``*`` gives
    the list of what it finds."""
    values = [record]
    wild = False
    for key in path.split("/"):
        nxt: list[Any] = []
        for v in values:
            if key == "*":
                wild = True
                items = v.values() if isinstance(v, Mapping) else v if isinstance(v, list) else []
                nxt.extend(x for x in items if x is not None)
            elif isinstance(v, Mapping):
                got = v.get(key, _MISSING)
                if got is not _MISSING and (got is not None or not wild):
                    nxt.append(got)
            elif isinstance(v, list) and key.lstrip("-").isdigit() and -len(v) <= int(key) < len(v):
                nxt.append(v[int(key)])
        if not wild and not nxt:
            raise FigureError(f"the record has no field {path!r}")
        values = nxt
    return values if wild else values[0]


def _mean(xs: list[float]) -> float:
    return sum(xs) / len(xs)


_FUNCTIONS: dict[str, Callable[[Any], Any]] = {
    "min": min, "max": max, "sum": sum, "len": len, "mean": _mean,
    "count": lambda xs: sum(bool(x) for x in xs)}
_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}


#: an expression that is one record path, unquoted
_BARE_PATH = re.compile(r"[\w.*-]+(?:/[\w.*-]+)*")


def evaluate(expr: str, record: Any) -> Any:
    """``expr`` (a value expression of the module docstring) on ``record``; nothing else of
    Python is evaluated."""
    if _BARE_PATH.fullmatch(expr):
        return lookup(record, expr)

    def ev(node: ast.AST) -> Any:
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            return lookup(record, node.value)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return node.value
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return _BINARY[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return -ev(node.operand)
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                and node.func.id in _FUNCTIONS and len(node.args) == 1 and not node.keywords):
            arg = ev(node.args[0])
            if not isinstance(arg, list) or (not arg and node.func.id in ("min", "max", "mean")):
                raise FigureError(f"{expr!r}: {node.func.id}() of {arg!r}")
            return _FUNCTIONS[node.func.id](arg)
        raise FigureError(f"{expr!r}: {ast.dump(node)} is not a value expression")

    try:
        return ev(ast.parse(expr, mode="eval").body)
    except SyntaxError as e:
        raise FigureError(f"{expr!r}: {e}") from e


# -- records --------------------------------------------------------------------------------------

def records(benchmark: str, measured: Path = MEASURED_DIR) -> list[Path]:
    """Every record of ``benchmark``, oldest first (names start with their UTC time)."""
    return sorted((measured / benchmark).glob("*.json"))


def matches(record: Any, where: Mapping[str, Any]) -> bool:
    """Whether every field of ``where`` holds its value in ``record``."""
    for path, want in where.items():
        try:
            if lookup(record, path) != want:
                return False
        except FigureError:
            return False
    return True


def record_of(fig: Figure, headline: Headline, measured: Path = MEASURED_DIR,
              use_where: bool = True) -> Path:
    """The record ``fig`` is computed from: its pinned record, else the newest record of its
    run's benchmark that matches the run's ``where`` (``use_where=False``: the newest of all,
    for the ``--quick`` check, whose small runs match no full-run filter)."""
    if fig.record is not None:
        path = MEASURED_DIR / fig.record
        if not path.is_file():
            raise FigureError(f"figure {fig.name}: pinned record {fig.record} does not exist")
        return path
    assert fig.run is not None
    run = headline.runs[fig.run]
    for path in reversed(records(run.benchmark, measured)):
        if not use_where or matches(json.loads(path.read_text()), run.where):
            return path
    raise FigureError(f"figure {fig.name}: no record of {run.benchmark} under {measured} "
                      f"matching {dict(run.where)}")


def _relative(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(REPO_ROOT))
    except ValueError:
        return str(path)


def figure_text(fig: Figure, record_path: Path) -> str:
    """What ``fig`` reads from the record at ``record_path``."""
    record = json.loads(record_path.read_text())
    values = {k: evaluate(v, record) for k, v in fig.values.items()}
    values.setdefault("record", _relative(record_path))
    values.setdefault("date", str(record.get("created_utc", ""))[:10])
    try:
        text = fig.format.format(**values)
    except (KeyError, ValueError, TypeError, IndexError) as e:
        raise FigureError(f"figure {fig.name}: format {fig.format!r}: {e!r}") from e
    if "\n" in text or "<!--" in text:
        raise FigureError(f"figure {fig.name}: {text!r} must be one line, no markers")
    return text


def all_figure_texts(headline: Headline, measured: Path = MEASURED_DIR,
                     use_where: bool = True) -> dict[str, str]:
    """Every figure's text, by name."""
    return {name: figure_text(fig, record_of(fig, headline, measured, use_where))
            for name, fig in headline.figures.items()}


# -- documents ------------------------------------------------------------------------------------

def marked(text: str) -> Iterator[tuple[int, str, str]]:
    """(line number, figure name, its text) of every marked figure in a document; a marker
    that does not open and close on one line is an error."""
    for k, line in enumerate(text.splitlines(), start=1):
        found = list(MARKER.finditer(line))
        if len(_OPEN.findall(line)) != len(found) or line.count(_CLOSE) != len(found):
            raise FigureError(f"line {k}: a fig marker that does not open and close on this line")
        for m in found:
            yield k, m["name"], m["text"]


def render_text(text: str, texts: Mapping[str, str]) -> str:
    """``text`` with every marked figure rewritten from ``texts``; an unknown name is an
    error (a figure in a document must have a spec)."""
    list(marked(text))   # malformed markers fail here

    def sub(m: re.Match[str]) -> str:
        if m["name"] not in texts:
            raise FigureError(f"fig:{m['name']} has no entry in {HEADLINE_TOML.name}")
        return f"<!-- fig:{m['name']} -->{texts[m['name']]}<!-- /fig -->"

    return MARKER.sub(sub, text)


def differences(text: str, texts: Mapping[str, str]) -> list[str]:
    """One line per marked figure of ``text`` that differs from what render writes."""
    out = []
    for line, name, got in marked(text):
        want = texts.get(name)
        if want is None:
            out.append(f"line {line}: fig:{name} has no entry in {HEADLINE_TOML.name}")
        elif got != want:
            out.append(f"line {line}: fig:{name} reads {got!r}, its record gives {want!r}")
    return out
