"""The sample's camera.yaml and aligned frames are what they were before the speed work (issue 34), byte for byte.

The digest (tests/_golden.py) was written by the code before issue 34's changes; speed work may not change an
output. Where numpy/scipy builds or the CPU's SIMD extensions differ from the machine that wrote it, bits may
differ legitimately: there the same numbers are asked for within a tolerance.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from _golden import GOLDEN, SAMPLE_PRED, _array_digest, fingerprint, sample_digest

pytestmark = pytest.mark.skipif(not SAMPLE_PRED.is_dir(), reason="sample_data/ is not in this checkout")


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    return json.loads(GOLDEN.read_text()), sample_digest(tmp_path_factory.mktemp("golden"))


def test_same_outputs_as_the_golden_run(outputs):
    golden, now = outputs
    assert sorted(now["arrays"]) == sorted(golden["arrays"])  # the same frames and keys
    assert len(now["arrays"]) >= 4 * 5  # every sample frame is there, with its keys
    if fingerprint() == golden["fingerprint"]:
        assert now["files"] == golden["files"]
        assert {k: v["sha256"] for k, v in now["arrays"].items()} == {k: v["sha256"] for k, v in golden["arrays"].items()}
    else:  # another numpy/scipy build or instruction set: the same numbers, within what such builds differ by
        for key, value in golden["camera"].items():
            assert math.isclose(now["camera"][key], value, rel_tol=1e-6, abs_tol=1e-9), key
        for key, value in golden["arrays"].items():
            for stat in ("sum", "abs_sum"):
                if stat in value:
                    assert math.isclose(now["arrays"][key][stat], value[stat], rel_tol=1e-6, abs_tol=1e-6), (key, stat)


def test_one_last_bit_changes_the_digest():
    """The exact comparison sees a one-ulp change that the tolerance comparison forgives."""
    a = np.linspace(0.5, 1.5, 10, dtype=np.float32)
    b = a.copy()
    b[3] = np.nextafter(b[3], np.float32(2.0))
    assert _array_digest(a)["sha256"] != _array_digest(b)["sha256"]
    assert math.isclose(_array_digest(a)["sum"], _array_digest(b)["sum"], rel_tol=1e-6)
