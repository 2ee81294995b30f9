"""Animations of the rendered frames: GIF (Pillow, always) and MP4 (PyAV, the optional ``rotavat[video]`` extra).

PyAV's wheels ship their own FFmpeg libraries (H.264 through libx264), so no system ffmpeg is
needed; ``av`` is imported only when an MP4 is asked for, and :func:`require_mp4` says how to
install it in one line (exit 2). H.264 in ``yuv420p`` (what every player reads) needs even
dimensions: frames are padded by one white pixel row/column when odd.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from ..files.atomic import atomic_open
from ..errors import InputError

__all__ = ["MP4_INSTALL", "require_mp4", "write_gif", "write_mp4"]

MP4_INSTALL = "pip install 'rotavat[video]'"  # the extra that brings PyAV


def require_mp4() -> Any:
    """The ``av`` module; InputError (exit 2) saying how to install it when it is missing."""
    try:
        import av  # lazy: optional extra rotavat[video]
    except ImportError:
        raise InputError(f"--mp4 needs PyAV, which is not installed: {MP4_INSTALL} (or use --gif)") from None
    return av


def write_gif(path: Path, images: list[np.ndarray], fps: float) -> Path:
    """(H, W, 3) uint8 frames as a looping GIF, atomically."""
    frames = [Image.fromarray(im).convert("P", palette=Image.ADAPTIVE, colors=255) for im in images]
    with atomic_open(path, "wb") as handle:
        frames[0].save(handle, format="GIF", save_all=True, append_images=frames[1:], duration=int(round(1000 / fps)), loop=0)
    return path


def _even(image: np.ndarray) -> np.ndarray:
    """Pad an (H, W, 3) image with white to even H and W (yuv420p needs them)."""
    H, W = image.shape[:2]
    return np.pad(image, ((0, H % 2), (0, W % 2), (0, 0)), constant_values=255) if H % 2 or W % 2 else image


def write_mp4(path: Path, images: list[np.ndarray], fps: float) -> Path:
    """(H, W, 3) uint8 frames (one size) as an H.264 MP4 at ``fps``, atomically."""
    av = require_mp4()
    frames = [_even(np.ascontiguousarray(im, dtype=np.uint8)) for im in images]
    H, W = frames[0].shape[:2]
    with atomic_open(path, "wb") as handle:
        with av.open(handle, mode="w", format="mp4") as container:
            codec = "libx264" if "libx264" in av.codecs_available else "mpeg4"  # a wheel without x264: MPEG-4 part 2
            stream = container.add_stream(codec, rate=Fraction(fps).limit_denominator(1000))
            stream.width, stream.height, stream.pix_fmt = W, H, "yuv420p"
            for image in frames:
                for packet in stream.encode(av.VideoFrame.from_ndarray(image, format="rgb24")):
                    container.mux(packet)
            for packet in stream.encode():  # flush
                container.mux(packet)
    return path
