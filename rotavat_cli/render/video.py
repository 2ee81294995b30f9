"""Animations of the rendered frames: GIF (Pillow, always) and MP4 (PyAV, the optional ``rotavat[video]`` extra).

Both take the frames as they come (:func:`gif_writer`, :func:`mp4_writer`: ``add`` one frame at a time): the
frames are spooled to a temporary file while the clip renders and encoded when the block ends, so rendering never
holds the clip. The MP4 is then encoded one frame at a time (x264 encoding beside the rendering, OpenGL on the same
cores, gave other bytes from run to run; after it, the same bytes every run, and the same as before). The GIF is
Pillow's own writer, fed one frame at a time, which keeps each frame it has taken (palettised, a third of the RGB
frame) until it writes the file: a long clip's GIF costs that memory, its MP4 does not.

PyAV's wheels ship their own FFmpeg libraries (H.264 through libx264), so no system ffmpeg is
needed; ``av`` is imported only when an MP4 is asked for, and :func:`require_mp4` says how to
install it in one line (exit 2). H.264 in ``yuv420p`` (what every player reads) needs even
dimensions: frames are padded by one white pixel row/column when odd.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterable, Iterator
from fractions import Fraction
from pathlib import Path
from typing import IO, Any

import numpy as np
from PIL import Image

from ..files.atomic import atomic_open
from ..errors import InputError

__all__ = ["MP4_INSTALL", "require_mp4", "Mp4Stream", "gif_writer", "mp4_writer", "write_gif", "write_mp4"]

MP4_INSTALL = "pip install 'rotavat[video]'"  # the extra that brings PyAV


def require_mp4() -> Any:
    """The ``av`` module; InputError (exit 2) saying how to install it when it is missing."""
    try:
        import av  # lazy: optional extra rotavat[video]
    except ImportError:
        raise InputError(f"--mp4 needs PyAV, which is not installed: {MP4_INSTALL} (or use --gif)") from None
    return av


class Mp4Stream:
    """An H.264 MP4 (``yuv420p``; MPEG-4 part 2 from a PyAV wheel without x264) written frame by frame to
    ``handle``; its size is the first frame's (padded to even)."""

    def __init__(self, handle: IO[bytes], fps: float) -> None:
        self.av = require_mp4()
        self.fps = fps
        self.container = self.av.open(handle, mode="w", format="mp4")
        self.stream = None

    def add(self, image: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 frame (the first frame's size)."""
        frame = _even(np.ascontiguousarray(image, dtype=np.uint8))
        if self.stream is None:
            codec = "libx264" if "libx264" in self.av.codecs_available else "mpeg4"  # a wheel without x264: MPEG-4 part 2
            self.stream = self.container.add_stream(codec, rate=Fraction(self.fps).limit_denominator(1000))
            self.stream.width, self.stream.height, self.stream.pix_fmt = frame.shape[1], frame.shape[0], "yuv420p"
        for packet in self.stream.encode(self.av.VideoFrame.from_ndarray(frame, format="rgb24")):
            self.container.mux(packet)

    def close(self) -> None:
        """Flush the encoder and close the container."""
        if self.stream is None:
            raise ValueError("an MP4 needs at least one frame")
        for packet in self.stream.encode():  # flush
            self.container.mux(packet)
        self.container.close()


class _FrameSpool:
    """(H, W, 3) uint8 frames of one size kept in a temporary file (``handle``), read back one at a time."""

    def __init__(self, handle: IO[bytes]) -> None:
        self.handle = handle
        self.shape: tuple[int, ...] | None = None
        self.count = 0

    def add(self, image: np.ndarray) -> None:
        """Append one frame (the first frame's shape)."""
        frame = np.ascontiguousarray(image, dtype=np.uint8)
        if self.shape is None:
            self.shape = frame.shape
        elif frame.shape != self.shape:
            raise ValueError(f"frames of one animation must share a size: {frame.shape} after {self.shape}")
        self.handle.write(frame.tobytes())
        self.count += 1

    def frames(self) -> Iterator[np.ndarray]:
        """The frames in order, one in memory at a time."""
        self.handle.seek(0)
        size = int(np.prod(self.shape)) if self.shape is not None else 0
        for _ in range(self.count):
            yield np.frombuffer(self.handle.read(size), dtype=np.uint8).reshape(self.shape)


class _Animation:
    """An animation being written to ``path`` (atomically): :meth:`add` frames, done when its block ends."""

    def __init__(self, path: Path, stream: _FrameSpool) -> None:
        self.path, self.stream = path, stream

    def add(self, image: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 frame."""
        self.stream.add(image)


@contextlib.contextmanager
def gif_writer(path: Path, fps: float) -> Iterator[_Animation]:
    """A looping GIF at ``fps`` written to ``path`` from frames added one at a time, atomically (nothing when the
    block fails)."""
    with tempfile.TemporaryFile(prefix="rotavat-gif-") as handle:
        spool = _FrameSpool(handle)
        yield _Animation(Path(path), spool)
        write_gif(path, spool.frames(), fps)


@contextlib.contextmanager
def mp4_writer(path: Path, fps: float) -> Iterator[_Animation]:
    """An H.264 MP4 at ``fps`` written to ``path`` frame by frame, atomically (nothing when the block fails)."""
    require_mp4()  # before any frame: say how to install it
    with tempfile.TemporaryFile(prefix="rotavat-mp4-") as handle:
        spool = _FrameSpool(handle)
        yield _Animation(Path(path), spool)
        write_mp4(path, spool.frames(), fps)


def write_gif(path: Path, images: Iterable[np.ndarray], fps: float) -> Path:
    """(H, W, 3) uint8 frames (any iterable, taken one at a time) as a looping GIF, atomically: Pillow's
    ``save_all`` (255 adaptive colours per frame, one index left for transparency)."""
    frames = (Image.fromarray(im).convert("P", palette=Image.ADAPTIVE, colors=255) for im in images)  # one index free
    first = next(frames, None)
    if first is None:
        raise ValueError("a GIF needs at least one frame")
    with atomic_open(path, "wb") as handle:
        first.save(handle, format="GIF", save_all=True, append_images=frames, duration=int(round(1000 / fps)), loop=0)
    return path


def _even(image: np.ndarray) -> np.ndarray:
    """Pad an (H, W, 3) image with white to even H and W (yuv420p needs them)."""
    H, W = image.shape[:2]
    return np.pad(image, ((0, H % 2), (0, W % 2), (0, 0)), constant_values=255) if H % 2 or W % 2 else image


def write_mp4(path: Path, images: list[np.ndarray], fps: float) -> Path:
    """(H, W, 3) uint8 frames (one size; any iterable, taken one at a time) as an H.264 MP4 at ``fps``, atomically."""
    with atomic_open(path, "wb") as handle:
        stream = Mp4Stream(handle, fps)
        try:
            for image in images:
                stream.add(image)
        except BaseException:
            with contextlib.suppress(Exception):
                stream.container.close()
            raise
        stream.close()
    return path
