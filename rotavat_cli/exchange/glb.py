"""A glTF 2.0 binary file (``.glb``) written in two passes, so memory stays flat in the number of frames.

A GLB is a 12-byte header, a JSON chunk, then a BIN chunk (glTF 2.0 spec, "Binary glTF Layout"); each
chunk is padded to 4 bytes (JSON with spaces, BIN with zeros). The JSON comes first but describes the
BIN (every accessor's offset, count and, for ``POSITION``, its ``min``/``max``). So:

1. **layout** (:class:`BinLayout`): every buffer view is placed in the BIN before any vertex is computed;
   the JSON is then serialised once with the widest possible ``min``/``max`` numbers
   (:data:`PLACEHOLDER_BOUND`) to fix its length (:func:`json_chunk`);
2. **bytes** (:class:`GlbWriter`): the header, a blank JSON chunk of that length and the BIN are written
   to the temporary file, each array at its planned offset as it is computed; the real JSON (with the
   measured bounds, never longer) is written over the blank one at the end, padded with spaces.

Numbers: ``FLOAT`` data is little-endian float32; bounds are written as the exact float64 value of each
float32 (``float(np.float32(x))``), so a reader comparing them with the data in float32 finds them equal.

>>> layout = BinLayout()
>>> view = layout.view(12, name="a")
>>> layout.accessor(view, 0, FLOAT, 1, "VEC3"), layout.size
(0, 12)
>>> len(json_chunk({"asset": {"version": "2.0"}})) % 4
0
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np

__all__ = ["FLOAT", "UNSIGNED_BYTE", "UNSIGNED_SHORT", "UNSIGNED_INT", "ARRAY_BUFFER", "ELEMENT_ARRAY_BUFFER",
           "PLACEHOLDER_BOUND", "BinLayout", "GlbWriter", "json_chunk", "glb_size", "bounds_json", "index_component"]

# accessor.componentType (glTF 2.0 spec, "Accessor Data Types")
UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5121, 5123, 5125, 5126
_COMPONENT_BYTES = {UNSIGNED_BYTE: 1, UNSIGNED_SHORT: 2, UNSIGNED_INT: 4, FLOAT: 4}
_TYPE_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
# bufferView.target: vertex attributes, vertex indices (animation and skin data have none)
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
_GLB_HEADER_BYTES, _CHUNK_HEADER_BYTES = 12, 8
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942  # "JSON", "BIN\0" little-endian
# the float32 whose float64 text is the longest (23 characters): a bound's text is never wider
PLACEHOLDER_BOUND = float(np.float32(-3.4028234e38))


def _align4(n: int) -> int:
    """``n`` rounded up to a multiple of 4 (every chunk and buffer view starts 4-byte aligned)."""
    return (n + 3) & ~3


def index_component(n_points: int) -> tuple[int, type]:
    """(componentType, numpy dtype) of vertex indices into ``n_points`` points: 16 bits when they fit
    (the largest index must stay below 65535, glTF's primitive-restart value), else 32."""
    return (UNSIGNED_SHORT, np.uint16) if n_points <= 65535 else (UNSIGNED_INT, np.uint32)


@dataclass
class BinLayout:
    """The BIN chunk's plan: buffer views at 4-byte aligned offsets, the accessors into them, and the
    static data (known at layout time) to write at their offsets.

    ``static``: (byte offset in the BIN, bytes or a zero-argument callable returning them, made when written).
    """

    views: list[dict] = field(default_factory=list)
    accessors: list[dict] = field(default_factory=list)
    static: list[tuple[int, Any]] = field(default_factory=list)
    size: int = 0  # bytes of the BIN chunk so far (a multiple of 4)

    def view(self, byte_length: int, target: int | None = None, name: str | None = None, stride: int | None = None) -> int:
        """A new buffer view of ``byte_length`` bytes at the end of the BIN; its index. ``stride``: bytes from one
        vertex to the next, required when several vertex-attribute accessors share the view."""
        entry: dict[str, Any] = {"buffer": 0, "byteOffset": self.size, "byteLength": int(byte_length)}
        if stride is not None:
            entry["byteStride"] = int(stride)
        if target is not None:
            entry["target"] = target
        if name:
            entry["name"] = name
        self.views.append(entry)
        self.size = _align4(self.size + int(byte_length))
        return len(self.views) - 1

    def view_offset(self, view: int) -> int:
        """Byte offset of a buffer view in the BIN chunk."""
        return int(self.views[view]["byteOffset"])

    def accessor(self, view: int, byte_offset: int, component: int, count: int, kind: str,
                 bounds: tuple[list, list] | None = None, name: str | None = None) -> int:
        """A new accessor of ``count`` elements of ``kind`` (``VEC3``...) at ``byte_offset`` in ``view``; its index.

        bounds: (min, max) lists (required by glTF for ``POSITION`` and animation inputs), or None.
        """
        size = count * _TYPE_WIDTH[kind] * _COMPONENT_BYTES[component]
        if byte_offset % _COMPONENT_BYTES[component] or byte_offset + size > self.views[view]["byteLength"]:
            raise ValueError(f"accessor of {size} bytes at {byte_offset} does not fit buffer view {view}")
        entry: dict[str, Any] = {"bufferView": view, "componentType": component, "count": int(count), "type": kind}
        if byte_offset:
            entry["byteOffset"] = int(byte_offset)
        if bounds is not None:
            entry["min"], entry["max"] = bounds
        if name:
            entry["name"] = name
        self.accessors.append(entry)
        return len(self.accessors) - 1

    def static_array(self, data: np.ndarray | Callable[[], np.ndarray], byte_length: int, target: int | None = None,
                     name: str | None = None) -> int:
        """A buffer view holding ``data`` (an array, or a callable making it when the file is written: large
        static data need not be kept meanwhile), ``byte_length`` bytes; its index."""
        view = self.view(byte_length, target, name)
        self.static.append((self.view_offset(view), data))
        return view


def bounds_json(points: np.ndarray) -> tuple[list[float], list[float]]:
    """(min, max) of float32 points (N, C) as glTF accessor bounds: the exact value of each float32."""
    pts = np.asarray(points, dtype=np.float32).reshape(-1, np.shape(points)[-1])
    return pts.min(axis=0).astype(np.float64).tolist(), pts.max(axis=0).astype(np.float64).tolist()


def json_chunk(gltf: dict, length: int | None = None) -> bytes:
    """The JSON chunk's content: compact UTF-8 JSON padded with spaces to a multiple of 4, or to ``length``
    (ValueError if it does not fit: the layout's placeholder bounds were not the widest)."""
    text = json.dumps(gltf, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    size = _align4(len(text)) if length is None else length
    if len(text) > size or size % 4:
        raise ValueError(f"glTF JSON of {len(text)} bytes does not fit its reserved {size} bytes")
    return text + b" " * (size - len(text))


def glb_size(json_bytes: int, bin_bytes: int) -> int:
    """Total bytes of a GLB with a JSON chunk and a BIN chunk of these (padded) lengths."""
    return _GLB_HEADER_BYTES + 2 * _CHUNK_HEADER_BYTES + _align4(json_bytes) + _align4(bin_bytes)


class GlbWriter:
    """Writes a GLB into an open binary file: header and a blank JSON chunk of ``json_bytes``, the BIN chunk
    of ``layout.size`` bytes (zeros, then the layout's static data), arrays at BIN offsets
    (:meth:`write_at`), and the real JSON last (:meth:`finish`).

    handle: a file opened for writing and seeking (``atomic_open(path, "wb")``), empty.
    """

    def __init__(self, handle: IO[bytes], json_bytes: int, layout: BinLayout) -> None:
        if json_bytes % 4:
            raise ValueError("the JSON chunk's length must be a multiple of 4")
        self.handle, self.json_bytes, self.layout = handle, json_bytes, layout
        self.total = glb_size(json_bytes, layout.size)
        self.bin_start = _GLB_HEADER_BYTES + _CHUNK_HEADER_BYTES + json_bytes + _CHUNK_HEADER_BYTES
        handle.write(struct.pack("<4sII", b"glTF", 2, self.total))
        handle.write(struct.pack("<II", json_bytes, _JSON_CHUNK))
        handle.write(b" " * json_bytes)
        handle.write(struct.pack("<II", layout.size, _BIN_CHUNK))
        handle.truncate(self.total)  # the BIN's padding (and every byte not yet written) reads as zeros
        for offset, data in layout.static:
            self.write_at(offset, data() if callable(data) else data)

    def write_at(self, bin_offset: int, data: np.ndarray | bytes) -> None:
        """Write ``data`` (an array: its bytes in C order, little-endian) at ``bin_offset`` of the BIN chunk."""
        if isinstance(data, bytes):
            raw: bytes | memoryview = data
        else:
            array = np.asarray(data)
            raw = memoryview(np.ascontiguousarray(array, dtype=array.dtype.newbyteorder("<"))).cast("B")  # no copy
        if bin_offset < 0 or bin_offset + len(raw) > self.layout.size:
            raise ValueError(f"{len(raw)} bytes at BIN offset {bin_offset} overrun its {self.layout.size} bytes")
        self.handle.seek(self.bin_start + bin_offset)
        self.handle.write(raw)

    def finish(self, gltf: dict) -> None:
        """Write the final JSON over the blank chunk (same length, padded with spaces)."""
        self.handle.seek(_GLB_HEADER_BYTES + _CHUNK_HEADER_BYTES)
        self.handle.write(json_chunk(gltf, self.json_bytes))
        self.handle.seek(self.total)
