"""Camera frames in a LeRobot parquet: PNG bytes in, RGB arrays out, and their statistics.

Why PNG in the parquet and not videos: LeRobot v3 keeps a camera either as mp4 videos
(``dtype`` ``"video"``, which needs an ffmpeg-backed encoder and decoder) or as ``dtype``
``"image"``: its reader loads the data files with Hugging Face ``datasets`` whose features it
builds from info.json, ``datasets.Image()`` for an image feature, stored as Arrow's
``struct<bytes: binary, path: string>``; ``datasets`` decodes the bytes with Pillow and
LeRobot turns each into a (3, h, w) float32 tensor in [0, 1] (``hf_transform_to_torch``).
PNG is lossless, so what LeRobot reads is the rendered frame pixel for pixel; Pillow is a
base dependency already.
Their statistics are :func:`augment.export.lerobot_stats.image_stats`.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from PIL import Image

__all__ = ["decode_column", "encode_column"]


def _png(frame: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(frame, dtype=np.uint8), mode="RGB").save(buf, "PNG")
    return buf.getvalue()


def encode_column(pa: Any, frames: np.ndarray) -> Any:
    """(n, h, w, 3) uint8 frames as the Arrow column ``datasets.Image()`` reads: one
    ``{"bytes": PNG, "path": null}`` struct a row."""
    data = pa.array([_png(f) for f in frames], pa.binary())
    paths = pa.array([None] * len(frames), pa.string())
    return pa.StructArray.from_arrays([data, paths], names=["bytes", "path"])


def decode_column(col: Any) -> np.ndarray:
    """An image column as written by :func:`encode_column` back to (n, h, w, 3) uint8."""
    blobs = col.combine_chunks().field("bytes").to_pylist()
    return np.stack([np.asarray(Image.open(io.BytesIO(b)).convert("RGB")) for b in blobs])

