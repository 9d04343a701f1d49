"""The disk cache of AutoWS workspace clouds: its key and its file paths.

Clouds are cached in ``sim.paths.cache_dir()/workspace``, keyed by a SHA-256 (:func:`workspace_key`)
of the hand model (MJCF bytes plus the compiled kinematic and tip-mesh arrays, which cover included
files and meshes), the hand config (TOML bytes and the parsed finger/palm fields), the joint grids,
the parameters and the demo, and of :data:`augment.autows.cloud.FORMAT_VERSION`. The files
themselves are written and read by :class:`augment.autows.cloud.WorkspaceCloud`.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from augment.autows.cloud import FORMAT_VERSION
from augment.autows.params import AutoWSParams
from augment.autows.seed import DemoSeed
from sim.paths import cache_dir

if TYPE_CHECKING:
    from sim.hand.model import Hand

__all__ = ["cache_path", "workspace_key"]


def _hash_array(h: Any, a: np.ndarray) -> None:
    """Feed ``a`` (dtype, shape and bytes, C order) into the hash object ``h``."""
    a = np.ascontiguousarray(a)
    h.update(f"{a.dtype}{a.shape}".encode())
    h.update(a.tobytes())


def _model_digest(hand: Hand) -> str:
    """SHA-256 of what the clouds depend on in the hand model and config: the MJCF bytes, the
    compiled kinematic tree and tip-mesh arrays (these cover included files and mesh files
    without parsing the MJCF), and the config (TOML bytes plus parsed fields, so a config
    changed in code also changes the key)."""
    m = hand.model
    h = hashlib.sha256()
    h.update(hand.model_path.read_bytes())
    for name in ("body_parentid", "body_pos", "body_quat", "body_jntadr", "body_jntnum",
                 "jnt_type", "jnt_axis", "jnt_pos", "jnt_qposadr", "jnt_range", "jnt_limited",
                 "qpos0", "geom_bodyid", "geom_dataid", "geom_type", "geom_pos", "geom_quat"):
        _hash_array(h, getattr(m, name))
    for f in hand.config.fingers:
        mid = m.mesh(f.tip_mesh).id
        va, nv = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
        fa, nf = m.mesh_faceadr[mid], m.mesh_facenum[mid]
        _hash_array(h, m.mesh_vert[va:va + nv])
        _hash_array(h, m.mesh_face[fa:fa + nf])
    cfg = hand.config
    if cfg.file.is_file():
        h.update(cfg.file.read_bytes())
    fields = {"palm": [cfg.palm.body, cfg.palm.pos.tolist(), cfg.palm.quat_wxyz.tolist()],
              "fingers": [[f.name, f.tip_body, f.tip_mesh, list(f.links), list(f.joints),
                           sorted(f.coupled_to.items()), f.v_f.tolist(), f.v_u.tolist(),
                           f.tip_site_pos.tolist(), sorted(f.ranges_rad.items())]
                          for f in cfg.fingers]}
    h.update(json.dumps(fields, sort_keys=True, default=str).encode())
    return h.hexdigest()


def workspace_key(hand: Hand, params: AutoWSParams, demo: DemoSeed | None,
                  grids: Mapping[str, Mapping[str, np.ndarray]]) -> str:
    """Cache key of a build: hand model + config, parameters, joint grids and demo."""
    h = hashlib.sha256()
    h.update(f"dexaug-autows-v{FORMAT_VERSION}".encode())
    h.update(_model_digest(hand).encode())
    h.update(json.dumps(params.to_dict(), sort_keys=True).encode())
    for finger, grid in grids.items():
        h.update(finger.encode())
        for joint, values in grid.items():
            h.update(joint.encode())
            _hash_array(h, np.asarray(values, dtype=float))
    if demo is not None:
        h.update(demo.id.encode())
        _hash_array(h, demo.joints)
        for finger in sorted(demo.contacts):
            c = demo.contacts[finger]
            h.update(finger.encode())
            h.update(b"none" if c is None else c.tobytes())
    return h.hexdigest()


def cache_path(hand: Hand, key: str) -> Path:
    """Where the cloud of ``key`` is cached: ``cache_dir()/workspace/<hand>-<key[:24]>.npz``."""
    return cache_dir() / "workspace" / f"{hand.name}-{key[:24]}.npz"
