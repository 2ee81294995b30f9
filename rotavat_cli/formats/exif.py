"""The camera's own focal length from a photo's EXIF (``rotavat calibrate --image``).

A photo taken with the camera (same lens, same zoom) states its focal length in its EXIF, in one of
two ways rotavat can turn into pixels:

- ``FocalLengthIn35mmFilm`` (tag 0xA405): the 35 mm-equivalent focal (what phones write), converted
  at the photo's own size (:func:`~rotavat_cli.geometry.focal.focal_px_from_35mm`);
- else ``FocalLength`` (0x920A, mm) with the sensor's pixel pitch, ``FocalPlaneXResolution`` (0xA20E:
  image pixels per ``FocalPlaneResolutionUnit``, 0xA210: 2 inch, the default; 3 cm; 4 mm; 5 µm), so
  ``f_px = FocalLength * FocalPlaneXResolution / mm per unit`` (the sensor is the image width over it).

Anything else (a ``FocalLength`` alone: the sensor size unknown) gives no focal. Unlike the focal an
HPS method assumed, this is the camera's own, so it may be *given* to the calibration; it is in the
photo's pixels, and is carried to the sequence's image size by :meth:`PhotoFocal.at_size` (refused
when the shapes differ: another crop of the sensor). The file is read within ``limits.max_file_mb``
and only its header: the pixels are never decoded.

>>> from PIL.ExifTags import Base
>>> focal_px, tags = focal_from_exif({Base.FocalLengthIn35mmFilm: 26}, (4032, 3024))    # 26 / 43.27 * 5040 px
>>> round(focal_px, 2), tags
(3028.66, 'FocalLengthIn35mmFilm 26 mm')
>>> focal_from_exif({Base.FocalLength: 4.25, Base.FocalPlaneXResolution: 800.0, Base.FocalPlaneResolutionUnit: 4}, (4032, 3024))
(3400.0, 'FocalLength 4.25 mm and FocalPlaneXResolution 800 px/mm')
>>> focal_from_exif({Base.FocalLength: 4.25}, (4032, 3024))
(None, 'FocalLength 4.25 mm but no FocalPlaneXResolution (the sensor size)')
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from PIL import ExifTags, Image, UnidentifiedImageError

from ..errors import file_error
from ..geometry.focal import focal_px_at_size, focal_px_from_35mm
from ..unpickle.streams import file_size

__all__ = ["PhotoFocal", "focal_from_exif", "read_photo_focal"]

_FOCAL_35MM, _FOCAL_MM, _PLANE_X_RES, _PLANE_UNIT, _ORIENTATION = 0xA405, 0x920A, 0xA20E, 0xA210, 0x0112
# FocalPlaneResolutionUnit -> mm per unit: 2 inch (EXIF's default), 3 cm; 4 mm and 5 µm as some cameras write them
_MM_PER_UNIT = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}
_UNIT_NAMES = {2: "in", 3: "cm", 4: "mm", 5: "µm"}
_DEFAULT_UNIT = 2
_TURNED = (5, 6, 7, 8)  # EXIF Orientation values whose photo is shown turned a quarter: width and height swap


@dataclass(frozen=True)
class PhotoFocal:
    """What a photo's EXIF says of the camera's focal.

    image_size: (W, H) px as the photo is shown (EXIF Orientation applied); focal_px: on that image (None:
    its EXIF states no usable focal); tags: which tags gave it, or why none did.
    """

    path: Path
    image_size: tuple[int, int]
    focal_px: float | None
    tags: str

    def at_size(self, image_size: tuple[int, int]) -> float:
        """The focal (px) on the same camera's images of ``image_size`` (W, H), e.g. a video's frames: scaled by
        the width ratio (:func:`~rotavat_cli.geometry.focal.focal_px_at_size`); InputError naming the photo when its
        shape differs (another crop of the sensor) or it states no focal."""
        if self.focal_px is None:
            raise file_error(self.path, f"its EXIF states no focal length ({self.tags})")
        try:
            return focal_px_at_size(self.focal_px, self.image_size, image_size)
        except ValueError as exc:
            raise file_error(self.path, f"{exc}: the photo's focal does not carry over to the sequence's images "
                                        "(another crop of the sensor); pass --focal or --focal-mm") from None

    def source(self, image_size: tuple[int, int]) -> str:
        """The fit block's ``focal_source`` for this focal carried to ``image_size``."""
        size = "" if tuple(image_size) == self.image_size else (
            f", a {self.image_size[0]}x{self.image_size[1]} photo carried to {image_size[0]}x{image_size[1]}")
        return f"EXIF {self.tags} of {self.path}{size}"


def _positive(value: Any) -> float | None:
    """An EXIF number (int, IFDRational, float) as a positive finite float, else None (absent, 0 = unknown, 1/0)."""
    try:
        number = float(value)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return None
    return number if math.isfinite(number) and number > 0 else None


def focal_from_exif(tags: Mapping[int, Any], image_size: tuple[int, int]) -> tuple[float | None, str]:
    """The focal (px) EXIF ``tags`` (tag number -> value, IFD0 and the Exif IFD together) give on an image of
    ``image_size`` (W, H) px, and the words naming the tags that gave it; ``(None, why)`` when they give none.

    A focal in px does not depend on which way the photo is shown, nor does the diagonal the 35 mm rule uses.
    """
    mm35 = _positive(tags.get(_FOCAL_35MM))
    if mm35 is not None:
        return focal_px_from_35mm(mm35, image_size), f"FocalLengthIn35mmFilm {mm35:g} mm"
    focal_mm = _positive(tags.get(_FOCAL_MM))
    if focal_mm is None:
        return None, "neither FocalLengthIn35mmFilm nor FocalLength"
    x_res = _positive(tags.get(_PLANE_X_RES))
    unit = tags.get(_PLANE_UNIT, _DEFAULT_UNIT)
    if x_res is None or unit not in _MM_PER_UNIT:
        why = "no FocalPlaneXResolution (the sensor size)" if x_res is None else \
            f"FocalPlaneResolutionUnit {unit!r} is no length unit"
        return None, f"FocalLength {focal_mm:g} mm but {why}"
    return (focal_mm * x_res / _MM_PER_UNIT[unit],
            f"FocalLength {focal_mm:g} mm and FocalPlaneXResolution {x_res:g} px/{_UNIT_NAMES[unit]}")


def read_photo_focal(path: Path) -> PhotoFocal:
    """The focal a photo's EXIF states (:func:`focal_from_exif`) and its size, from its header only.

    InputError naming the file when it is missing, a folder, over ``limits.max_file_mb`` or not an image
    Pillow can read.
    """
    path = Path(path)
    file_size(path)
    try:
        with warnings.catch_warnings():  # the pixels are never decoded: a huge photo is no decompression bomb
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as img:  # reads the header only
                width, height = img.size
                # a PNG keeps its EXIF after the pixels, which Pillow would decode to reach it: only one stated before
                exif = img.getexif() if img.format != "PNG" or "exif" in img.info else Image.Exif()
                tags = {**dict(exif), **dict(exif.get_ifd(ExifTags.IFD.Exif))}
    except (OSError, UnidentifiedImageError, Image.DecompressionBombError, SyntaxError, ValueError, EOFError) as exc:
        raise file_error(path, f"not a readable image ({exc})") from None
    if width < 1 or height < 1:
        raise file_error(path, f"not a readable image (its header says {width}x{height} px)")
    if tags.get(_ORIENTATION) in _TURNED:
        width, height = height, width
    focal_px, words = focal_from_exif(tags, (width, height))
    return PhotoFocal(path, (width, height), focal_px, words)
