"""The .npy header read without compiling (issue 34): numpy's own headers by a pattern, everything else as a Python
literal; both ways give what ``ast.literal_eval`` gives, and what the pattern refuses still gets its literal reading."""

from __future__ import annotations

import ast
import io

import numpy as np
import pytest

from rotavat_cli.unpickle import npy as npy_module
from rotavat_cli.unpickle.npy import parse_npy_header

DTYPES = ["<f4", ">f8", "<i8", "|u1", "|b1", "<c16", "<U7", "|S3", "<M8[ns]", "<m8[s]", "<f2", "|V4"]
SHAPES = [(), (0,), (3,), (2, 3), (1, 6890, 3), (10**9,), (4, 0, 2)]


def numpy_header(dtype: str, shape: tuple, fortran: bool = False) -> str:
    """The header text np.save writes for such an array."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": fortran, "shape": shape})
    return buf.getvalue()[10:].decode("latin1")


def literal(text: str) -> tuple:
    header = ast.literal_eval(text)
    return np.lib.format.descr_to_dtype(header["descr"]), tuple(int(s) for s in header["shape"]), bool(header["fortran_order"])


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("shape", SHAPES)
def test_numpys_own_headers_read_by_the_pattern_as_the_literal_reads_them(dtype, shape, monkeypatch):
    text = numpy_header(dtype, shape, fortran=len(shape) == 2)
    assert npy_module._NUMPY_HEADER.match(text), text  # the fast path, not the fallback
    assert parse_npy_header(text) == literal(text)


def test_the_pattern_never_disagrees_with_the_literal_on_mutated_headers():
    """Every header numpy writes, one character changed, dropped or doubled: where the pattern matches, it reads
    what the literal reads; where it does not, the literal decides (same value, or the same refusal)."""
    rng = np.random.default_rng(34)
    alphabet = list("{}()[],:' 0123456789<>|fFiuTrueFalsdcrshpt_\n")
    checked = matched = 0
    for dtype in DTYPES[:6]:
        for shape in SHAPES:
            text = numpy_header(dtype, shape)
            for _ in range(40):
                i = int(rng.integers(len(text)))
                op = rng.integers(3)
                mutated = (text[:i] + rng.choice(alphabet) + text[i + 1:] if op == 0 else
                           text[:i] + text[i + 1:] if op == 1 else text[:i] + text[i] + text[i:])
                try:
                    expected = literal(mutated)
                except (ValueError, SyntaxError, KeyError, TypeError):
                    expected = "refused"
                try:
                    got = parse_npy_header(mutated)
                except (ValueError, SyntaxError, KeyError, TypeError):
                    got = "refused"
                assert got == expected, mutated
                matched += bool(npy_module._NUMPY_HEADER.match(mutated))
                checked += 1
    assert checked == 6 * len(SHAPES) * 40 and matched > 0


def test_headers_numpy_does_not_write_still_read_as_literals():
    record = "{'descr': [('x', '<f4'), ('y', '<i2')], 'fortran_order': False, 'shape': (5,), }"
    assert parse_npy_header(record) == (np.dtype([("x", "<f4"), ("y", "<i2")]), (5,), False)
    assert parse_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (1_000,), }")[1] == (1000,)
    with pytest.raises((ValueError, SyntaxError)):
        parse_npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (__import__('os'),), }")
