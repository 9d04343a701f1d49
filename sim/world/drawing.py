"""Raster helpers on RGB images held as NumPy arrays (H, W, 3) uint8, with Pillow: PNG and JPEG
encoding, decoding, and :class:`Canvas`, which draws points, lines, arrows, markers and text on
such an array in place (the report figures, the AutoWS overlay).

Pixel coordinates: x to the right, y down, (0, 0) the centre of the top-left pixel; colours RGB.
Text uses Pillow's bundled scalable font (``ImageFont.load_default(size=...)``, Pillow ≥ 10.1), so
no system font files are needed.
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterable
from functools import cache
from types import TracebackType

import numpy as np
from PIL import Image, ImageDraw, ImageFont

__all__ = ["Canvas", "decode_rgb", "encode_jpeg", "encode_png"]

Colour = tuple[int, int, int]
Point = tuple[float, float]

#: coordinates are clamped to this many pixels either way (a point projected from just in front
#: of a camera can land absurdly far off the image, past what Pillow's C integers hold)
_FAR_PX = 1_000_000


def _to_image(rgb: np.ndarray) -> Image.Image:
    a = np.asarray(rgb)
    if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"expected an RGB image (H, W, 3) uint8, got shape {a.shape} {a.dtype}")
    return Image.fromarray(np.ascontiguousarray(a))


def _encode(rgb: np.ndarray, fmt: str, **options: object) -> bytes:
    buf = io.BytesIO()
    _to_image(rgb).save(buf, fmt, **options)
    return buf.getvalue()


def encode_png(rgb: np.ndarray) -> bytes:
    """PNG bytes of an RGB (H, W, 3) uint8 image."""
    return _encode(rgb, "PNG")


def encode_jpeg(rgb: np.ndarray, quality: int) -> bytes:
    """JPEG bytes of an RGB (H, W, 3) uint8 image at ``quality`` (0–100)."""
    return _encode(rgb, "JPEG", quality=int(quality))


def decode_rgb(data: bytes) -> np.ndarray:
    """An encoded image (PNG, JPEG, …) as RGB (H, W, 3) uint8."""
    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB")).copy()


@cache
def _font(size_px: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=size_px)


def _xy(p: Iterable[float]) -> Point:
    x, y = p
    return (min(max(float(x), -_FAR_PX), _FAR_PX), min(max(float(y), -_FAR_PX), _FAR_PX))


class Canvas:
    """Draws on an RGB (H, W, 3) uint8 array in place: ``with Canvas(img) as c: c.line(...)``;
    the drawing is written back into ``img`` when the block ends. Shapes are not anti-aliased
    (a shape's pixels have exactly its colour); text is."""

    def __init__(self, img: np.ndarray) -> None:
        self.img = img
        self.image = _to_image(img)
        self.draw = ImageDraw.Draw(self.image)

    def __enter__(self) -> Canvas:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.img[...] = np.asarray(self.image)

    def disk(self, centre: Iterable[float], radius: float, colour: Colour) -> None:
        """A filled circle of ``radius`` pixels around ``centre``."""
        x, y = _xy(centre)
        self.draw.ellipse((x - radius, y - radius, x + radius, y + radius), fill=colour)

    def line(self, start: Iterable[float], end: Iterable[float], colour: Colour,
             width: int = 1) -> None:
        self.polyline([start, end], colour, width)

    def polyline(self, points: Iterable[Iterable[float]], colour: Colour, width: int = 1,
                 closed: bool = False) -> None:
        """Segments through ``points`` (N, 2) in order; back to the first when ``closed``."""
        pts = [_xy(p) for p in points]
        if closed and pts:
            pts.append(pts[0])
        if len(pts) >= 2:
            self.draw.line(pts, fill=colour, width=width, joint="curve" if width > 1 else None)

    def arrow(self, start: Iterable[float], end: Iterable[float], colour: Colour, width: int = 1,
              tip: float = 0.1) -> None:
        """A line from ``start`` to ``end`` with two barbs at ``end``, ``tip`` × its length long,
        at 45° to it."""
        (x0, y0), (x1, y1) = _xy(start), _xy(end)
        size = tip * math.hypot(x1 - x0, y1 - y0)
        back = math.atan2(y0 - y1, x0 - x1)
        self.line((x0, y0), (x1, y1), colour, width)
        for turn in (math.pi / 4, -math.pi / 4):
            self.line((x1, y1), (x1 + size * math.cos(back + turn), y1 + size * math.sin(back + turn)),
                      colour, width)

    def diamond(self, centre: Iterable[float], colour: Colour, size: int = 16,
                width: int = 1) -> None:
        """A diamond outline ``size`` pixels tall and wide around ``centre``."""
        x, y = _xy(centre)
        h = size / 2
        self.polyline([(x, y - h), (x + h, y), (x, y + h), (x - h, y)], colour, width, closed=True)

    def text(self, origin: Iterable[float], text: str, colour: Colour, size_px: int = 14,
             bold: bool = False) -> None:
        """``text`` in a ``size_px`` font with its baseline starting at ``origin``."""
        self.draw.text(_xy(origin), text, fill=colour, font=_font(int(size_px)), anchor="ls",
                       stroke_width=1 if bold else 0)
