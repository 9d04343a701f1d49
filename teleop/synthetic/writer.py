"""Record a synthetic episode (or any frames) as an MCAP session that replays like a real
recording (:func:`write_session`): ``/hands`` plus a ``grasp_mark`` event.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from teleop.messages import HandFrame
from teleop.synthetic.episode import SynthEpisode

__all__ = ["write_session"]

logger = logging.getLogger(__name__)


def write_session(frames: Sequence[HandFrame] | SynthEpisode, path: Path | str,
                  metadata: Mapping[str, Any] | None = None, *,
                  grasp_time_s: float | None = None, overwrite: bool = False) -> Path:
    """Write a synthetic session as MCAP with :class:`teleop.record.recorder.SessionRecorder`:
    ``/hands`` (every frame, logged at its receive time) and ``/events`` (``grasp_mark`` at
    ``grasp_time_s``, device clock; taken from the episode when one is given). Log times are
    the frames' receive times on a fixed epoch, so the file is identical for equal inputs
    apart from the recorder's own creation metadata."""
    from teleop.record.recorder import SessionRecorder

    meta: dict[str, Any] = {}
    if isinstance(frames, SynthEpisode):
        meta.update(frames.metadata)
        if grasp_time_s is None:
            grasp_time_s = frames.grasp_time_s
        frame_list = list(frames.frames)
    else:
        frame_list = list(frames)
    meta.update(metadata or {})
    if not frame_list:
        raise ValueError("no frames to write")
    epoch_ns = 1_700_000_000 * 10**9
    t_first = frame_list[0].receive_time_s

    def log_ns(t_s: float) -> int:
        return epoch_ns + round((t_s - t_first) * 1e9)

    path = Path(path)
    with SessionRecorder(path, metadata=meta, overwrite=overwrite,
                         start_time_ns=epoch_ns) as rec:
        marked = grasp_time_s is None
        for frame in frame_list:
            if not marked and grasp_time_s is not None and frame.device_time_s >= grasp_time_s:
                rec.write_event("grasp_mark", {"source": "synth", "device_time_s": grasp_time_s},
                                log_time_ns=log_ns(frame.receive_time_s))
                marked = True
            rec.write_hands(frame, log_time_ns=log_ns(frame.receive_time_s))
    logger.info("wrote %d synthetic frames to %s", len(frame_list), path)
    return path
