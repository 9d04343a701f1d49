"""Offline hand trajectories → raw-input sessions: :func:`load_trajectory` reads a keypoint file,
:func:`import_trajectory` writes it as a session that ``dexaug rerecord`` (and ``dexaug replay``)
take like a headset recording.

Why a session: everything downstream — the bridge, demo extraction, augmentation — starts from
a recording's ``/hands``. Writing imported data in exactly that form (the layout the synthetic
operator writes: ``/hands`` at the frames' receive times on a fixed epoch) means no consumer
needs to know where a trajectory came from; the metadata says it (file, SHA-256, format,
space, frame rate, side).

Files (positions in metres, see :mod:`teleop.input.keypoints` for layouts and spaces):

- ``.pkl``: a list of (J,3) arrays or one (T,J,3) array (dex-retargeting's MediaPipe dumps).
  Only numpy arrays (and the lists holding them) are unpickled: a pickle can run any code;
- ``.npy``: one (T,J,3) array;
- ``.npz``: ``keypoints`` (T,J,3), optionally the object's poses in the same space:
  ``object_pos_m`` (T,3) and ``object_quat_wxyz`` (T,4; default identity).

Object poses go into the session twice: the first one as the metadata ``object_pos_m`` /
``object_quat_wxyz`` (what :func:`teleop.bridge.rerecord.rerecord` places the object by; the
bridge rests it on its table, so x, y and the yaw carry over), and every one on ``/tf``
(``world`` → ``object``, in the ``/hands`` frames' space, before the bridge's
``world_offset_m``) at its frame's time, so the given motion stays with the session.
"""

from __future__ import annotations

import hashlib
import logging
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.io import atomic_path
from sim.transforms import mat_to_quat, quat_to_mat
from teleop.input.keypoints import Anchor, KeypointError, keypoint_frames
from teleop.record.foxglove import FrameTransform
from teleop.record.recorder import SessionRecorder
from teleop.record.schemas import FRAME_OBJECT, FRAME_WORLD
from teleop.record.session import SessionError
from teleop.retarget.config import load_hand_mapping

__all__ = ["ImportedSession", "Trajectory", "import_trajectory", "load_trajectory"]

logger = logging.getLogger(__name__)

Array = np.ndarray

#: Log time of the first frame (ns since the Unix epoch): a fixed epoch, as the synthetic
#: operator's, so equal inputs give equal files (apart from the recorder's creation metadata).
_EPOCH_NS = 1_700_000_000 * 10**9
_PICKLE_ALLOWED = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
                   ("numpy", "ndarray"), ("numpy", "dtype")}


class _ArrayUnpickler(pickle.Unpickler):
    """Unpickles numpy arrays (and the builtin containers around them), no other class."""

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in _PICKLE_ALLOWED:
            raise pickle.UnpicklingError(f"refusing to unpickle {module}.{name} (only numpy arrays "
                                         "are read)")
        return super().find_class(module, name)


@dataclass(frozen=True)
class Trajectory:
    """A keypoint file's content: ``points`` (T,J,3) metres; the object's poses (T,3) metres and
    (T,4) wxyz in the same space, or None; ``path`` where it was read from."""

    points: Array
    object_pos_m: Array | None
    object_quat_wxyz: Array | None
    path: Path


def _float_array(value: Any, where: str, field: str, shape: tuple[int | None, ...]) -> Array:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise KeypointError(f"{where}: {field}: not an array of numbers") from None
    if arr.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, arr.shape,
                                                                              strict=True)):
        want = ", ".join("N" if s is None else str(s) for s in shape)
        raise KeypointError(f"{where}: {field}: expected shape ({want}), got {arr.shape}")
    return arr


def load_trajectory(path: Path | str) -> Trajectory:
    """Read a keypoint file (module docstring); :class:`KeypointError` naming the file and field
    on anything else."""
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise KeypointError(f"{where}: no such file")
    obj_pos = obj_quat = None
    try:
        if path.suffix == ".pkl":
            with path.open("rb") as f:
                data = _ArrayUnpickler(f).load()
            points = _float_array(data, where, "keypoints", (None, None, 3))
        elif path.suffix == ".npy":
            points = _float_array(np.load(path, allow_pickle=False), where, "keypoints", (None, None, 3))
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                if "keypoints" not in z:
                    raise KeypointError(f"{where}: keypoints: missing array (has {sorted(z.files)})")
                points = _float_array(z["keypoints"], where, "keypoints", (None, None, 3))
                n = len(points)
                if "object_pos_m" in z:
                    obj_pos = _float_array(z["object_pos_m"], where, "object_pos_m", (n, 3))
                    obj_quat = (_float_array(z["object_quat_wxyz"], where, "object_quat_wxyz", (n, 4))
                                if "object_quat_wxyz" in z else np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)))
                elif "object_quat_wxyz" in z:
                    raise KeypointError(f"{where}: object_quat_wxyz: given without object_pos_m")
        else:
            raise KeypointError(f"{where}: unknown file type {path.suffix!r} (expected .pkl, .npy "
                                "or .npz)")
    except (pickle.UnpicklingError, EOFError, OSError, ValueError) as exc:
        raise KeypointError(f"{where}: cannot read the trajectory: {exc}") from None
    if obj_pos is not None and obj_quat is not None:
        norms = np.linalg.norm(obj_quat, axis=1)
        if not (np.isfinite(obj_pos).all() and np.isfinite(norms).all() and (norms > 0.5).all()):
            raise KeypointError(f"{where}: object_pos_m/object_quat_wxyz: expected finite positions "
                                "and unit quaternions in every frame")
        obj_quat = obj_quat / norms[:, None]
    return Trajectory(points, obj_pos, obj_quat, path)


@dataclass(frozen=True)
class ImportedSession:
    """What :func:`import_trajectory` wrote: the session ``path``, its ``frames`` (tracked
    ones: ``tracked``), their span ``duration_s`` and the ``metadata`` recorded."""

    path: Path
    frames: int
    tracked: int
    duration_s: float
    metadata: dict[str, Any]


def _object_world_poses(pos_m: Array, quat_wxyz: Array, rot: Array, t: Array) -> tuple[Array, Array]:
    """Object poses (T,3), (T,4) mapped like the keypoints: p ↦ R p + t, orientation ↦ R ·
    orientation (the object keeps its own body axes)."""
    return pos_m @ rot.T + t, mat_to_quat(np.einsum("ij,tjk->tik", rot, quat_to_mat(quat_wxyz)))


def import_trajectory(src: Path | str, out: Path | str, *, fmt: str, side: str, fps: float,
                      hand: str, space: str = "hand", object_name: str | None = None,
                      anchor: Anchor | None = None, overwrite: bool = False) -> ImportedSession:
    """Convert the keypoint file ``src`` (``fmt`` layout, a ``side`` hand in ``space``, ``fps``
    frames per second) into the raw-input session ``out`` for robot hand ``hand`` (whose
    retargeting mapping must follow the same side), with ``object_name`` on the table.

    Written through a temporary name: on any error nothing appears at ``out``. Raises
    :class:`KeypointError` (bad input, naming the file and field), :class:`sim.errors.ConfigError`
    (no mapping for ``hand``) or :class:`SessionError` (``out`` exists and not ``overwrite``)."""
    src, out = Path(src), Path(out)
    mapping = load_hand_mapping(hand)
    if mapping.side != side:
        raise KeypointError(f"{src}: side: the trajectory is a {side} hand but robot hand {hand!r} "
                            f"is driven by the operator's {mapping.side} hand ({mapping.file})")
    if out.exists() and not overwrite:
        raise SessionError(f"{out}: a session already exists there (pass overwrite to replace it)")
    traj = load_trajectory(src)
    if traj.object_pos_m is not None and not object_name:
        raise KeypointError(f"{src}: object_pos_m: object poses given but no object named")
    frames, rot, t = keypoint_frames(traj.points, fmt=fmt, side=side, fps=fps, space=space,
                                     anchor=anchor, where=str(src), source=f"import:{src.name}")
    meta: dict[str, Any] = {
        "hand": hand, "side": side, "synthetic": False, "source_file": str(src.resolve()),
        "source_sha256": hashlib.sha256(src.read_bytes()).hexdigest(), "source_format": fmt,
        "source_space": space, "fps": fps, "source_frames": len(frames)}
    poses = None
    if object_name:
        meta["object"] = object_name
    if traj.object_pos_m is not None and traj.object_quat_wxyz is not None:
        poses = _object_world_poses(traj.object_pos_m, traj.object_quat_wxyz, rot, t)
        meta.update(object_pos_m=poses[0][0].tolist(), object_quat_wxyz=poses[1][0].tolist(),
                    object_poses="/tf world→object: the given poses, in the /hands frames' space")
    with atomic_path(out) as tmp, SessionRecorder(tmp, metadata=meta, overwrite=True,
                                                  start_time_ns=_EPOCH_NS) as rec:
        for i, frame in enumerate(frames):
            log_ns = _EPOCH_NS + round(frame.receive_time_s * 1e9)
            if poses is not None:
                rec.write_tf([FrameTransform(FRAME_WORLD, FRAME_OBJECT, poses[0][i], poses[1][i])],
                             log_time_ns=log_ns)
            rec.write_hands(frame, log_time_ns=log_ns)
    tracked = sum(1 for f in frames if (h := f.hand(side)) is not None and h.tracked)
    logger.info("imported %d frames (%d tracked) of %s into %s", len(frames), tracked, src, out)
    return ImportedSession(out, len(frames), tracked,
                           frames[-1].device_time_s - frames[0].device_time_s, meta)
