"""Packaging is honest: what the code imports is declared, the licence is the one shipped, the
constraints file pins what the declared dependencies install, and `make demo` installs no extras.

Fast and offline: reads pyproject.toml, constraints.txt, LICENSE and the Makefile, parses the
package sources with ``ast`` and asks ``importlib.metadata`` about the installed distributions.
"""

from __future__ import annotations

import ast
import importlib.metadata as md
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

try:
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name
    from packaging.version import Version
except ImportError:  # pragma: no cover - pip always vendors it
    from pip._vendor.packaging.requirements import Requirement
    from pip._vendor.packaging.utils import canonicalize_name
    from pip._vendor.packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
CODE_DIRS = ("sim", "augment", "teleop", "dexaug", "benchmarks")
CONSTRAINTS = ROOT / "constraints.txt"
#: scripts run by another project's interpreter (e.g. LeRobot's reader in LeRobot's venv):
#: their imports are that venv's dependencies, not this project's
OUTSIDE = ROOT / "benchmarks" / "outside"

# Import names of distributions that need not be installed here (the `gpu` extra), which
# packages_distributions() therefore cannot map.
KNOWN_IMPORTS = {"warp": "warp-lang", "mujoco_warp": "mujoco-warp"}

# The first release of a dependency that has an attribute the code uses (checked against the
# released wheels); the declared lower bound must not be older.
API_FLOORS = {
    "mink": {"DofFreezingTask": "1.0.0", "NoSolutionFound": "0.0.12"},
}


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _requirements(extras: bool = True) -> list[Requirement]:
    proj = _project()
    reqs = [Requirement(r) for r in proj["dependencies"]]
    if extras:
        for group in proj.get("optional-dependencies", {}).values():
            reqs += [Requirement(r) for r in group]
    return reqs


def _declared_names() -> set[str]:
    return {canonicalize_name(r.name) for r in _requirements()}


def _local_tops() -> set[str]:
    tops = {p.name for p in ROOT.iterdir() if p.is_dir() and not p.name.startswith(".")}
    return tops | {p.stem for p in ROOT.glob("*.py")}


def _imported_tops() -> dict[str, set[str]]:
    """Top-level third-party module name -> files importing it (static and import_module("x"))."""
    skip = set(sys.stdlib_module_names) | _local_tops() | {"__future__"}
    found: dict[str, set[str]] = {}
    for d in CODE_DIRS:
        for path in sorted((ROOT / d).rglob("*.py")):
            if OUTSIDE in path.parents:
                continue
            tree = ast.parse(path.read_text(), str(path))
            for node in ast.walk(tree):
                names: list[str] = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                elif (isinstance(node, ast.Call) and node.args
                      and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
                      and ((isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                           or (isinstance(node.func, ast.Name) and node.func.id == "__import__"))):
                    names = [node.args[0].value]
                for name in names:
                    top = name.split(".")[0]
                    if top and top not in skip:
                        found.setdefault(top, set()).add(str(path.relative_to(ROOT)))
    return found


def test_every_third_party_import_is_declared():
    assert (ROOT / "sim").is_dir()
    declared = _declared_names()
    mapping = md.packages_distributions()
    problems = []
    imported = _imported_tops()
    assert "mujoco" in imported and "numpy" in imported   # the scan does see the code
    for top, files in sorted(imported.items()):
        dists = {canonicalize_name(d) for d in mapping.get(top, [])}
        if top in KNOWN_IMPORTS:
            dists.add(canonicalize_name(KNOWN_IMPORTS[top]))
        where = ", ".join(sorted(files)[:3])
        if not dists:
            problems.append(f"{top} ({where}): no installed distribution provides it")
        elif not dists & declared:
            problems.append(f"{top} ({where}): provided by {sorted(dists)}, none declared in pyproject")
    assert not problems, "undeclared imports:\n" + "\n".join(problems)


def test_declared_bounds_cover_the_api_the_code_uses():
    sources = "\n".join(p.read_text() for d in CODE_DIRS for p in (ROOT / d).rglob("*.py"))
    reqs = {canonicalize_name(r.name): r for r in _requirements(extras=False)}
    for dist, floors in API_FLOORS.items():
        spec = reqs[dist].specifier
        lower = [Version(s.version) for s in spec if s.operator in (">=", "==", "~=", ">")]
        assert lower, f"{dist}: no lower bound in {spec}"
        for attr, first in floors.items():
            if re.search(rf"\b{dist}\.{attr}\b", sources):
                assert max(lower) >= Version(first), (
                    f"the code uses {dist}.{attr}, first released in {dist} {first}, "
                    f"but pyproject allows {dist}{spec}")


def test_license_file_matches_spdx_expression():
    proj = _project()
    text = (ROOT / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    assert "TERMS AND CONDITIONS FOR USE, REPRODUCTION, AND DISTRIBUTION" in text
    assert "END OF TERMS AND CONDITIONS" in text          # the whole text, not a stub
    assert proj["license"] == "Apache-2.0"                 # SPDX string, not the old table form
    assert proj.get("license-files") == ["LICENSE"]
    assert not [c for c in proj.get("classifiers", []) if c.startswith("License ::")]
    build = tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]["requires"]
    st = [Requirement(r) for r in build if canonicalize_name(Requirement(r).name) == "setuptools"]
    assert st and not st[0].specifier.contains("76.99"), "PEP 639 license fields need setuptools>=77"


def _pins() -> dict[str, Version]:
    pins: dict[str, Version] = {}
    for line in CONSTRAINTS.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        req = Requirement(line)
        ops = [s for s in req.specifier if s.operator == "=="]
        assert len(ops) == 1 and len(req.specifier) == 1, f"not an exact pin: {line!r}"
        pins[canonicalize_name(req.name)] = Version(ops[0].version)
    return pins


def _installed_closure(reqs: list[Requirement]) -> set[str]:
    """The installed distributions that `reqs` pull in, transitively (markers and extras honoured)."""
    seen: set[str] = set()
    todo = [(r, ()) for r in reqs]
    while todo:
        req, extras = todo.pop()
        if req.marker and not any(req.marker.evaluate({"extra": e}) for e in (extras or ("",))):
            continue
        name = canonicalize_name(req.name)
        try:
            dist = md.distribution(name)
        except md.PackageNotFoundError:
            continue
        key = f"{name}[{','.join(sorted(req.extras))}]"
        if key in seen:
            continue
        seen.add(key)
        todo += [(Requirement(r), tuple(req.extras)) for r in (dist.requires or [])]
    return {k.split("[")[0] for k in seen}


def test_constraints_pin_everything_and_respect_the_bounds():
    pins = _pins()
    assert "dexaug" not in pins                       # the editable project itself is not pinned
    missing = [canonicalize_name(r.name) for r in _requirements(extras=False)
               if canonicalize_name(r.name) not in pins]
    assert not missing, f"base dependencies not pinned in constraints.txt: {missing}"
    unpinned = sorted(_installed_closure(_requirements()) - set(pins))
    assert not unpinned, f"installed requirements not pinned in constraints.txt: {unpinned}"
    bad = [f"{r.name}{r.specifier} but pinned {pins[canonicalize_name(r.name)]}"
           for r in _requirements()
           if canonicalize_name(r.name) in pins
           and not r.specifier.contains(pins[canonicalize_name(r.name)], prereleases=True)]
    assert not bad, "pins outside pyproject's bounds:\n" + "\n".join(bad)


def _dry_run(target: str) -> list[str]:
    if shutil.which("make") is None:
        pytest.skip("no make")
    out = subprocess.run(["make", "-n", "-B", "--no-print-directory", target], cwd=ROOT,
                         capture_output=True, text=True, timeout=30, check=True).stdout
    return [ln for ln in out.splitlines() if re.search(r"pip install\b", ln) and "--upgrade pip" not in ln]


def _extras(line: str) -> set[str]:
    m = re.search(r"-e\s+'?\"?\.\[([^\]]*)\]", line)
    return {e.strip() for e in m.group(1).split(",")} if m else set()


def test_make_demo_installs_no_extras_and_both_installs_are_constrained():
    demo = _dry_run("demo")
    assert demo, "make demo installs nothing?"
    for line in demo:
        assert not _extras(line) & {"dev", "ray"}, f"make demo installs extras: {line}"
        assert "-c constraints.txt" in line, f"unconstrained install: {line}"
    test = _dry_run("test")
    assert any({"dev", "ray"} <= _extras(line) for line in test), test
    assert all("-c constraints.txt" in line for line in test), test
