"""Where an import's image size (W, H) px comes from when the tool does not store it: the user's
``--image-size``, a principal point at the image centre, a PNG/JPEG header; and the centred square
ROMP/BEV/PHALP pad the image to."""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import Any

import numpy as np

from ..geometry.camera import MAX_IMAGE_SIDE_PX
from ..errors import file_error
from .imported import ImportOptions

__all__ = ["centre_image_size", "image_size_from_header", "need_image_size", "padded_square"]


def need_image_size(opts: ImportOptions, source: Any, why: str) -> tuple[int, int]:
    """The user's --image-size, or an InputError saying to pass it."""
    if opts.image_size is None:
        raise file_error(source, f"the image size is not stored in this file ({why}); pass --image-size W H")
    return opts.image_size


def centre_image_size(cx: float, cy: float, source: Any, what: str) -> tuple[int, int]:
    """(W, H) = (2 cx, 2 cy) px rounded, for tools whose principal point is the image centre; InputError
    unless both are within 1..MAX_IMAGE_SIDE_PX (the contract's bound)."""
    size = (2.0 * float(cx), 2.0 * float(cy))
    if not all(np.isfinite(v) and 1 <= v <= MAX_IMAGE_SIDE_PX for v in size):
        raise file_error(source, f"{what} ({float(cx):.6g}, {float(cy):.6g}) px is not the centre of an image of at "
                                 f"most {MAX_IMAGE_SIDE_PX} px: pass --image-size W H")
    return round(size[0]), round(size[1])


def image_size_from_header(path: Path) -> tuple[int, int] | None:
    """(W, H) read from a PNG or JPEG header, or None (missing, unreadable or other formats)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(32)
            if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
                return struct.unpack(">II", head[16:24])
            if head[:2] != b"\xff\xd8":
                return None
            handle.seek(2)
            for _ in range(1000):  # walk the JPEG segments to the first start-of-frame marker
                marker = handle.read(2)
                if len(marker) < 2 or marker[0] != 0xFF:
                    return None
                length = struct.unpack(">H", handle.read(2))[0]
                if marker[1] in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
                    height, width = struct.unpack(">HH", handle.read(5)[1:5])
                    return (width, height)
                handle.seek(length - 2, os.SEEK_CUR)
    except (OSError, struct.error):
        return None
    return None


def padded_square(image_size: tuple[int, int]) -> tuple[int, int, int]:
    """(S, left, top) of the centred zero-padding to a square used by ROMP/BEV/PHALP: S = max(W, H)."""
    width, height = image_size
    side = max(width, height)
    return side, (side - width) // 2, (side - height) // 2
