"""``dexaug`` renders in a shell with no display and no ``MUJOCO_GL`` (an SSH session, a container).

Before dexaug/headless_gl.py, ``dexaug augment`` typed there got as far as its report and then
stopped with "FatalError: an OpenGL platform library has not been loaded" (MuJoCo fell back to
GLFW, which needs a display).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from dexaug.headless_gl import default_headless_gl
from sim.paths import REPO_ROOT


def test_a_set_backend_or_a_display_is_left_alone() -> None:
    found = {"EGL": "libEGL.so.1", "OSMesa": "libOSMesa.so.8"}.get
    env = {"MUJOCO_GL": "osmesa"}
    assert default_headless_gl(env, found) is None and env == {"MUJOCO_GL": "osmesa"}
    env = {"DISPLAY": ":0"}
    assert default_headless_gl(env, found) is None and "MUJOCO_GL" not in env
    env = {}
    assert default_headless_gl(env, found) == "egl" and env["MUJOCO_GL"] == "egl"
    env = {}
    assert default_headless_gl(env, {"OSMesa": "libOSMesa.so.8"}.get) == "osmesa"
    env = {}
    assert default_headless_gl(env, lambda _: None) is None and env == {}


def test_augment_renders_its_report_with_no_display_and_no_backend(tmp_path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY",
                                                             "PYOPENGL_PLATFORM")}
    demo = REPO_ROOT / "recordings" / "demos" / "062_dice.json"
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "dexaug.cli", "augment", str(demo), "--n", "4",
                           "--validate", "none", "--workers", "1", "--gallery", "1",
                           "--out", str(out)], cwd=REPO_ROOT, env=env, capture_output=True,
                          text=True, timeout=900, check=False)
    assert done.returncode in (0, 3), done.stdout[-1500:] + done.stderr[-1500:]
    assert "OpenGL" not in done.stderr, done.stderr[-1500:]
    (folder,) = [p for p in out.iterdir() if p.is_dir()]
    assert (folder / "report.html").stat().st_size > 0
    assert list(folder.glob("*.png")), sorted(p.name for p in folder.iterdir())
    assert json.loads((folder / "summary.json").read_text())
