"""The versions of the packages a result depends on, for provenance.

Why: a dataset or a benchmark row is only comparable with another made by the same simulator
and libraries (MuJoCo's contact solver changes between releases; DexGraspBench's verdicts were
made with MuJoCo 3.3.2). Versions are read from the installed distributions' metadata, so
nothing is imported to find them.
"""

from __future__ import annotations

from importlib import metadata

__all__ = ["PACKAGES", "package_versions"]

#: distribution names whose versions a result records (missing ones are left out)
PACKAGES = ("dexaug", "mujoco", "mink", "numpy", "scipy", "h5py", "eclipse-zenoh", "mcap")


def package_versions(packages: tuple[str, ...] = PACKAGES) -> dict[str, str]:
    """Distribution name → installed version, for those of ``packages`` that are installed."""
    out: dict[str, str] = {}
    for name in packages:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out
