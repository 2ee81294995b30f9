"""The sample's outputs, fingerprinted: what speed work must leave byte for byte (issue 34).

``sample_digest(out_dir)`` runs ``rotavat calibrate`` and ``rotavat align`` on the committed sample
(``sample_data/scene/pred``, as ``make run`` does) in this process and returns, for each output, the
sha256 of its bytes (camera.yaml, the aligned camera.yaml and people.csv) or of each aligned array
(dtype, shape and data: an ``.npz`` file's own bytes hold zip timestamps), plus sums of the arrays and
the camera's numbers for a comparison with a tolerance on another machine.

Floating point is bit-for-bit reproducible only with the same numpy and scipy builds on the same
instruction set (numpy dispatches its loops to the CPU's SIMD extensions), so the digest records that
``fingerprint()``; tests/test_golden_outputs.py asks for the same bytes where it matches and for the
same numbers within a tolerance elsewhere.

Regenerate (only when an output is meant to change, and say why in the commit):

    .venv/bin/python tests/_golden.py --write
"""

from __future__ import annotations

import hashlib
import json
import platform
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_PRED = ROOT / "sample_data" / "scene" / "pred"
GOLDEN = Path(__file__).resolve().parent / "golden" / "sample_outputs.json"


def fingerprint() -> dict:
    """What bit-for-bit floating point depends on: numpy and scipy versions, machine, numpy's SIMD extensions."""
    import scipy

    simd = np.show_config(mode="dicts").get("SIMD Extensions", {})
    return {"numpy": np.__version__, "scipy": scipy.__version__, "machine": platform.machine(),
            "simd": sorted(simd.get("found", []))}


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _array_digest(array: np.ndarray) -> dict:
    """sha256 of an array's dtype, shape and bytes, and its sum (float arrays) for a tolerance comparison."""
    out = {"sha256": _sha(f"{array.dtype.str}{array.shape}".encode() + np.ascontiguousarray(array).tobytes())}
    if array.dtype.kind == "f":
        out["sum"] = float(np.sum(array, dtype=np.float64))
        out["abs_sum"] = float(np.sum(np.abs(array), dtype=np.float64))
    return out


def _numbers(tree, prefix: str = "") -> dict[str, float]:
    """Every number of a YAML tree by its path (``fit.std.focal_px``), for a tolerance comparison."""
    if isinstance(tree, dict):
        return {k: v for key, value in tree.items() for k, v in _numbers(value, f"{prefix}{key}.").items()}
    if isinstance(tree, list):
        return {k: v for i, value in enumerate(tree) for k, v in _numbers(value, f"{prefix}{i}.").items()}
    if isinstance(tree, (int, float)) and not isinstance(tree, bool):
        return {prefix.rstrip("."): float(tree)}
    return {}


def sample_digest(out_dir: Path) -> dict:
    """Calibrate and align the sample into ``out_dir`` (``rotavat`` in this process); the outputs' digest."""
    from typer.testing import CliRunner

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _cli import invoke

    camera_yaml, aligned = out_dir / "camera.yaml", out_dir / "pred_aligned"
    runner = CliRunner()
    for args in (("calibrate", SAMPLE_PRED, "--out", camera_yaml, "--quiet"),
                 ("align", SAMPLE_PRED, "--camera", camera_yaml, "--out", aligned, "--quiet")):
        result = invoke(runner, *args)
        assert result.exit_code == 0, (args, result.output)
    files = {"camera.yaml": camera_yaml, "pred_aligned/camera.yaml": aligned / "camera.yaml",
             "pred_aligned/people.csv": aligned / "people.csv"}
    arrays = {}
    for frame in sorted(aligned.glob("*.npz")):
        with np.load(frame, allow_pickle=False) as npz:
            arrays.update({f"pred_aligned/{frame.name}/{key}": _array_digest(npz[key]) for key in sorted(npz.files)})
    return {"files": {name: _sha(path.read_bytes()) for name, path in files.items()}, "arrays": arrays,
            "camera": _numbers(yaml.safe_load(camera_yaml.read_text()))}


def main() -> None:
    """``--write``: compute the digest with this checkout's code and write tests/golden/sample_outputs.json."""
    if sys.argv[1:] != ["--write"]:
        sys.exit(__doc__)
    with tempfile.TemporaryDirectory() as tmp:
        digest = sample_digest(Path(tmp))
    GOLDEN.parent.mkdir(exist_ok=True)
    GOLDEN.write_text(json.dumps({"fingerprint": fingerprint(), **digest}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {GOLDEN}")


if __name__ == "__main__":
    main()
