"""Pick MuJoCo's offscreen OpenGL backend where no display is and none was asked for.

Why: without ``MUJOCO_GL`` MuJoCo renders through GLFW, which needs a display; in an SSH shell
or a container the first render (``dexaug augment``'s report, a gallery, an episode camera)
then aborts with "an OpenGL platform library has not been loaded". ``make`` exports
``MUJOCO_GL=egl``, a user typing ``dexaug augment`` does not. MuJoCo reads the variable once,
when it is imported, so this runs in the CLI before any command imports it; it only looks for
the libraries (no probe process), and a ``MUJOCO_GL`` the user set always wins.
"""

from __future__ import annotations

import ctypes.util
import os
from collections.abc import Callable, MutableMapping

__all__ = ["HEADLESS_BACKENDS", "default_headless_gl"]

#: MuJoCo's offscreen backends, best first, with the shared library each loads
HEADLESS_BACKENDS = (("egl", "EGL"), ("osmesa", "OSMesa"))


def default_headless_gl(env: MutableMapping[str, str] | None = None,
                        find_library: Callable[[str], str | None] = ctypes.util.find_library
                        ) -> str | None:
    """Set ``MUJOCO_GL`` in ``env`` (default ``os.environ``) to the first backend of
    :data:`HEADLESS_BACKENDS` whose library is installed, when it is unset and there is no
    display (``DISPLAY``, ``WAYLAND_DISPLAY``); returns the backend set, else None."""
    env = os.environ if env is None else env
    if env.get("MUJOCO_GL") or env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return None
    for backend, library in HEADLESS_BACKENDS:
        if find_library(library):
            env["MUJOCO_GL"] = backend
            return backend
    return None
