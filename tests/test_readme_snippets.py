"""The code blocks of the README and the guides under docs/: every ```python and ```bash
block says whether it runs, and those that run, run.

Each such block is preceded by a marker line (an HTML comment, invisible on the rendered page):
``<!-- snippet: run -->`` or ``<!-- snippet: skip (why) -->``; a block without one fails
:func:`test_every_block_is_marked`, so a new block cannot slip in untested unnoticed. Usage
synopses (``[--n 200]``, ``<demo>``), live sessions and minute-long jobs are skipped with their
reason; the rest run in a scratch folder laid out as the repository root after ``make demo``:
``.venv`` and ``recordings`` (links to the checkout's) and ``datasets/`` as ``dexaug demo``
writes it (the real command, at ``--n 4``: ~10 s once per session). Python blocks run with the
venv's Python, bash blocks with ``bash -eu``, both with ``MUJOCO_GL=egl``, and must exit 0.
"""

from __future__ import annotations

import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from sim.paths import REPO_ROOT
from tests.conftest import HANG_S, needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow

#: the front door and its guides (docs/*.md; the decision records hold no runnable blocks)
DOCUMENTS = (REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md")))
VENV = REPO_ROOT / ".venv"
LANGUAGES = ("python", "bash")
SNIPPET_TIMEOUT_S = HANG_S   # a hang bound only: a block runs in seconds
_FENCE = re.compile(r"^(?P<indent>\s*)```(?P<lang>\S*)\s*$")
_MARKER = re.compile(r"^\s*<!--\s*snippet:\s*(?P<action>run|skip)\s*(?:\((?P<why>.*)\))?\s*-->\s*$")


@dataclass(frozen=True)
class Block:
    """One fenced code block: where it opens (1-based line), its language and text (dedented
    by the fence's indentation), and its marker (``run``/``skip`` and the reason; None: no
    marker, or a malformed one)."""

    line: int
    lang: str
    code: str
    action: str | None
    why: str
    doc: str = "README.md"

    @property
    def name(self) -> str:
        return f"{self.doc}:{self.line}:{self.lang}"


def _marker(lines: list[str], fence: int) -> tuple[str | None, str]:
    """The marker on the last non-blank line above line index ``fence``: (action, reason)."""
    for above in reversed(lines[:fence]):
        if above.strip():
            m = _MARKER.match(above)
            return (m["action"], (m["why"] or "").strip()) if m else (None, "")
    return None, ""


def parse_blocks(text: str, doc: str = "README.md") -> list[Block]:
    """Every fenced block of a Markdown text, in order (an unclosed one runs to the end)."""
    lines, blocks, k = text.splitlines(), [], 0
    while k < len(lines):
        m = _FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        end = next((j for j in range(k + 1, len(lines)) if lines[j].strip() == "```"), len(lines))
        indent = len(m["indent"])
        code = "\n".join(line[min(indent, len(line) - len(line.lstrip())):]   # dedent
                         for line in lines[k + 1:end])
        blocks.append(Block(k + 1, m["lang"], code + "\n", *_marker(lines, k), doc))
        k = end + 1
    return blocks


BLOCKS = [b for path in DOCUMENTS
          for b in parse_blocks(path.read_text(), str(path.relative_to(REPO_ROOT)))
          if b.lang in LANGUAGES]
RUNS = [b for b in BLOCKS if b.action == "run"]


def test_the_parser_finds_blocks_markers_and_unmarked_ones() -> None:
    text = ("# t\n<!-- snippet: run -->\n```bash\necho hi\n```\n\n"
            "1. item:\n   <!-- snippet: skip (synopsis) -->\n   ```python\n   x = [1]\n   ```\n"
            "<!-- snippet: skip -->\n```bash\nls\n```\n"
            "Text.\n```python\nprint()\n```\n")
    got = [(b.line, b.lang, b.code, b.action, b.why) for b in parse_blocks(text)]
    assert got == [(3, "bash", "echo hi\n", "run", ""),
                   (9, "python", "x = [1]\n", "skip", "synopsis"),
                   (13, "bash", "ls\n", "skip", ""),
                   (17, "python", "print()\n", None, "")]


def test_every_block_is_marked() -> None:
    """Each python/bash block of the README and docs is marked to run, or skipped with a
    reason."""
    assert len(BLOCKS) >= 8, [b.name for b in BLOCKS]   # the parser still sees the blocks
    bad = [b.name for b in BLOCKS
           if b.action is None or (b.action == "skip" and not b.why)]
    assert not bad, ("README code blocks without a marker line `<!-- snippet: run -->` or "
                     f"`<!-- snippet: skip (why) -->` above them: {bad}")
    assert RUNS, "no README block is marked to run"


@pytest.fixture(scope="session")
def after_make_demo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scratch repository root as ``make demo`` leaves it: the venv and recordings, and
    ``datasets/`` written by the real ``dexaug demo`` (with --n 4 instead of 100, for time)."""
    root = tmp_path_factory.mktemp("readme")
    for name in (".venv", "recordings"):
        (root / name).symlink_to(REPO_ROOT / name)
    proc = subprocess.run([str(VENV / "bin" / "dexaug"), "demo", "--n", "4"], cwd=root,
                          env=_env(), capture_output=True, text=True, timeout=HANG_S, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return root


def _env() -> dict[str, str]:
    path = os.pathsep.join([str(VENV / "bin"), os.environ.get("PATH", "")])
    return {**os.environ, "MUJOCO_GL": "egl", "PATH": path,
            "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO_ROOT),
                                                        os.environ.get("PYTHONPATH")]))}


def _command(block: Block) -> list[str]:
    if block.lang == "python":
        return [str(VENV / "bin" / "python"), "-c", block.code]
    return ["bash", "-eu", "-c", block.code]


@needs_menagerie
@needs_ycb
@pytest.mark.parametrize("block", RUNS, ids=[b.name for b in RUNS])
def test_a_block_marked_to_run_runs(block: Block, after_make_demo: Path) -> None:
    proc = subprocess.run(_command(block), cwd=after_make_demo, env=_env(), capture_output=True,
                          text=True, timeout=SNIPPET_TIMEOUT_S, check=False)
    assert proc.returncode == 0, (f"{block.name} exited {proc.returncode}:\n{block.code}\n"
                                  f"{proc.stdout[-2000:]}{proc.stderr[-3000:]}")
