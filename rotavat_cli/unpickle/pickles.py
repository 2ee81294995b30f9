"""Pickle files (``pickle.dump``, ``joblib.dump``) unpickled with the allow-list, never by the
standard unpickler.

- plain pickles, protocols 0-5 (Python 2 pickles are read with ``encoding='latin1'``);
- ``joblib.dump`` files, uncompressed or zlib/gzip/bz2/xz/lzma-compressed: joblib writes each
  numpy array as a ``joblib.numpy_pickle.NumpyArrayWrapper`` placeholder followed by the raw array
  bytes (``joblib/numpy_pickle.py``); the placeholder is replaced by an inert stand-in and the
  bytes are read into the array it declares, refused when fewer follow;
- torch tensors inside plain pickles (``np.save`` of a dict of tensors) come back as numpy arrays
  (:class:`~rotavat_cli.unpickle.torch_files.TensorUnpickler`).

A compressed pickle is unpickled as it inflates, never inflated whole first: a decompression bomb
is refused at its first byte that is not a pickle's, or once ``max_file_mb`` came out, holding one
chunk.

Examples
--------
>>> import pickle
>>> import numpy as np
>>> loads(pickle.dumps({"a": [1, 2.5], "b": np.arange(3)}), "demo.pkl")["b"].tolist()
[0, 1, 2]
>>> import os
>>> class Evil:
...     def __reduce__(self):
...         return (os.system, ("echo pwned",))
>>> loads(pickle.dumps(Evil()), "evil.pkl")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: evil.pkl: refused to unpickle global 'posix.system' (only numpy arrays, numpy scalars and builtin containers are allowed)
"""

from __future__ import annotations

import bz2
import io
import lzma
import zlib
from typing import Any, BinaryIO

from ..errors import InputError
from .expansion import check_expansion
from .refusal import unpickling_errors
from .streams import INFLATE_CHUNK, Inflater, Stream
from .torch_files import TensorUnpickler
from .torch_tensors import resolve

__all__ = ["decompressed", "load_pickle_bytes", "load_stream", "loads"]


def load_stream(file: BinaryIO, source: str, drain: bool = False) -> Any:
    """Unpickle one object from ``file``; every failure becomes a one-line InputError. ``drain``: read
    the rest of the stream too (a compressed stream's checksum and size are checked at its end)."""
    with unpickling_errors(source):
        unpickler = TensorUnpickler(file)
        value = unpickler.load()
        if drain:
            while file.read(INFLATE_CHUNK):
                pass
        if unpickler.named_torch:  # torch tensors pickled by plain pickle (np.save of a dict of tensors)
            value = resolve(value)
        check_expansion(value)
        return value


def loads(data: bytes, source: str) -> Any:
    """Unpickle ``data`` (plain pickle or uncompressed joblib) with the allow-list."""
    return load_stream(io.BytesIO(data), source)


def decompressed(data: bytes, source: str) -> BinaryIO:
    """The pickle stream of a file's bytes: joblib's optional compression undone as it is read
    (detected from the magic bytes, as joblib does)."""
    for magic, make in ((b"\x1f\x8b", lambda: zlib.decompressobj(16 + zlib.MAX_WBITS)), (b"BZh", bz2.BZ2Decompressor),
                        (b"\xfd7zXZ\x00", lambda: lzma.LZMADecompressor(format=lzma.FORMAT_XZ)),
                        (b"]\x00\x00\x80\x00", lambda: lzma.LZMADecompressor(format=lzma.FORMAT_ALONE)),
                        (b"x", zlib.decompressobj)):  # zlib header (joblib's default compressor)
        if data.startswith(magic):
            return Stream(Inflater(make, data))
    if data[:4] == b'\x04"M\x18':
        raise InputError(f"{source}: lz4-compressed joblib files are not supported; re-save with compress=3 (zlib)")
    return io.BytesIO(data)


def load_pickle_bytes(data: bytes, source: str) -> Any:
    """Unpickle a pickle file's bytes, written by ``pickle.dump`` or ``joblib.dump`` (any compression)."""
    stream = decompressed(data, source)
    return load_stream(stream, source, drain=isinstance(stream, Stream))
