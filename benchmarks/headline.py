"""The README's Status figures and the docs' result figures, from benchmark records.

Two jobs (``make bench-headline`` runs both):

``run``
    Reruns exactly the benchmarks behind the figures (the ``[runs]`` of
    ``benchmarks/headline.toml``), each writing its record under ``benchmarks/measured/``
    (~15 min on 2 cores). ``--quick`` runs each at CI size instead, with its records in a
    scratch folder (``DEXAUG_RECORD_DIR``, read by :func:`benchmarks.record.write_record`) so
    that they never become headline figures, and then computes every figure from them: the
    benchmarks still run and still write the fields the figures read.
``render``
    Rewrites every marked figure (``<!-- fig:NAME -->…<!-- /fig -->``) of README.md and
    docs/*.md from the newest matching record (:mod:`benchmarks.figures`); ``--check`` changes
    nothing and exits 1 when a document differs from its records.

Usage: ``.venv/bin/python benchmarks/headline.py run [--quick] [--only RUN ...]``,
``.venv/bin/python benchmarks/headline.py render [--check]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.figures import (
    DOCUMENTS,
    REPO_ROOT,
    FigureError,
    Headline,
    all_figure_texts,
    differences,
    figure_text,
    load_headline,
    record_of,
    render_text,
)
from benchmarks.record import RECORD_DIR_ENV


def _env(record_dir: Path | None) -> dict[str, str]:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO_ROOT),
                                                       os.environ.get("PYTHONPATH")]))}
    if record_dir is not None:
        env[RECORD_DIR_ENV] = str(record_dir)
    return env


def run(headline: Headline, quick: bool, only: list[str]) -> int:
    """Each run's command (full or quick) with this Python from the repository root; with
    ``quick`` the records go to a scratch folder and every figure is computed from them."""
    unknown = sorted(set(only) - set(headline.runs))
    if unknown:
        raise SystemExit(f"unknown runs {unknown}; known: {sorted(headline.runs)}")
    chosen = [r for r in headline.runs.values() if not only or r.name in only]
    with tempfile.TemporaryDirectory(prefix="dexaug-headline-") as scratch:
        for r in chosen:   # quick: one scratch folder per run (runs may share a benchmark)
            cmd = [sys.executable, *(r.quick if quick else r.command)]
            print(f"== {r.name}: {' '.join(cmd[1:])}", flush=True)
            proc = subprocess.run(cmd, cwd=REPO_ROOT, check=False,
                                  env=_env(Path(scratch, r.name) if quick else None))
            if proc.returncode != 0:
                print(f"{r.name} exited {proc.returncode}", file=sys.stderr)
                return proc.returncode
        if not quick:
            return 0
        for r in chosen:
            for fig in (f for f in headline.figures.values() if f.run == r.name):
                try:
                    text = figure_text(fig, record_of(fig, headline, Path(scratch, r.name),
                                                      use_where=False))
                except FigureError as e:
                    print(f"the quick records do not give fig:{fig.name}: {e}", file=sys.stderr)
                    return 1
                print(f"fig:{fig.name} (quick run) = {text}")
    return 0


def render(headline: Headline, check: bool) -> int:
    """Rewrite (or, ``check``: compare) every marked figure of the documents."""
    texts = all_figure_texts(headline)
    stale = 0
    for doc in DOCUMENTS:
        old = doc.read_text()
        diffs = differences(old, texts)
        for d in diffs:
            print(f"{doc.relative_to(REPO_ROOT)}: {d}")
        stale += len(diffs)
        if diffs and not check:
            doc.write_text(render_text(old, texts))
    if check and stale:
        print(f"{stale} figures differ from their records: run "
              "`.venv/bin/python benchmarks/headline.py render`", file=sys.stderr)
        return 1
    print(f"{len(texts)} figures {'checked' if check else 'rendered'}; {stale} "
          f"{'differ' if check else 'changed'}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="job", required=True)
    r = sub.add_parser("run", help="rerun the benchmarks behind the figures")
    r.add_argument("--quick", action="store_true",
                   help="CI-size runs, records in a scratch folder, figures computed from them")
    r.add_argument("--only", nargs="*", default=[], help="these runs of headline.toml only")
    c = sub.add_parser("render", help="rewrite the marked figures from the records")
    c.add_argument("--check", action="store_true", help="change nothing; exit 1 on a difference")
    args = ap.parse_args()
    headline = load_headline()
    if args.job == "run":
        return run(headline, args.quick, args.only)
    return render(headline, args.check)


if __name__ == "__main__":
    raise SystemExit(main())
