#!/usr/bin/env python3
"""``make fuzz``: a randomized campaign against rotavat's hostile-input rules (issue 15).

Each iteration takes a valid input (a contract sequence in npz or OBJ form, a --config file, or the
output of one of the sixteen HPS tools rotavat imports), damages one of its files at random and
runs the command that reads it; every run is checked against the rules of the fixed corpus
(harness.py): exit 0 with a correct result or exit 2 with one ``error:`` line naming the input,
inputs unchanged, nothing foreign touched, nothing left behind, no payload, bounded memory and time.

Mutations: byte flips, truncation at a random offset, inserted/zeroed/duplicated byte ranges; for
npz files member deletion, duplication and renaming (including path-like names), dtype and shape
changes and injected NaN/inf/huge values inside a member; for pickles the same on the unpickled
tree (re-pickled with a random protocol, joblib layout kept); for torch files (``torch.save`` zip
archives, legacy streams, ``np.save`` of dicts of tensors) the same on the loaded tree, re-saved with
its tensors as torch's, or damage to the archive's records (storages); for YAML and JSON keys and
values; for OBJ numbers and indices.

Before the iterations, the slow measured cases of the corpus (``corpus.slow_cases``: memory and time
bombs too slow for ``make test``) run as real processes (``--no-slow`` skips them).

Every ``--memory-every``-th run is a real process with its peak RSS measured (rule 4); the others
run in this process (fast). Iteration ``i`` is reproducible: ``--seed S --only i --keep DIR``.

    python tests/fuzz/run_fuzz.py                      # default: 3000 iterations (~3 min), seed 0
    python tests/fuzz/run_fuzz.py --iterations 200 --seed 7
    python tests/fuzz/run_fuzz.py --only 42 --keep /tmp/case42   # replay one iteration, keep its folder

Exit status 1 when any run broke a rule.
"""

from __future__ import annotations

import argparse
import io
import json
import pickle
import re
import shutil
import sys
import tempfile
import time
import zipfile
import zlib
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make tests/ importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from fuzz import corpus as C  # noqa: E402
from fuzz import harness as H  # noqa: E402

DEFAULT_ITERATIONS = 3000  # about 3 minutes on 2 cores


# =================================================================================================
# Bases: valid inputs, the files a mutation may target, and the commands that read them
# =================================================================================================
@dataclass
class Base:
    name: str
    files: dict[str, Any]
    targets: list[str]  # files a mutation may damage
    commands: list[tuple[str, list[str], list[str], list]]  # (name, args, outputs, checks)
    inputs: list[str]


def _contract_commands(form: str) -> list[tuple[str, list[str], list[str], list]]:
    cmds = [("info", ["info", "seq"], [], []),
            ("align", ["align", "--in", "seq", "--camera", "cam.yaml", "--out", "out"], ["out"],
             [C.check_seq("out", 3, None, form=form)])]
    if form == "npz":
        cmds += [("calibrate", ["calibrate", "seq", "--out", "cal.yaml"], ["cal.yaml"], [C.check_camera_yaml("cal.yaml")]),
                 ("eval", ["eval", "seq", "--gt", "gt", "--out", "ev"], ["ev"], [C.check_files("ev/metrics.json")]),
                 ("export", ["export", "seq", "--camera", "cam.yaml", "--out", "e.glb"], ["e.glb"],
                  [C.check_files("e.glb")])]
    return cmds


def bases() -> list[Base]:
    out = []
    seq = dict(C.base_seq())
    out.append(Base("contract-npz", seq, [k for k in seq if k.startswith("seq/")] + ["cam.yaml"],
                    _contract_commands("npz"), C.SEQ_INPUTS))
    obj = {**C.contract_seq("seq", form="obj"), "cam.yaml": C.camera_yaml()}
    out.append(Base("contract-obj", obj, [k for k in obj if k.startswith("seq/")], _contract_commands("obj"),
                    ["seq", "cam.yaml"]))
    config = {**seq, "config.yaml": b"align:\n  upright: paper\n  height_from: frame\n  jobs: 1\n"
                                     b"  stature_range_m: [1.0, 2.3]\ncalibrate:\n  method: refine\n"
                                     b"  person_height_m: 1.7\n  grid:\n    steps: [20, 20, 20]\n"}
    out.append(Base("config", config, ["config.yaml"],
                    [("align", C.ALIGN + ["--config", "config.yaml"], ["out"], [C.check_seq("out", 3, None)]),
                     ("calibrate", ["calibrate", "seq", "--out", "cal.yaml", "--config", "config.yaml"], ["cal.yaml"],
                      [C.check_camera_yaml("cal.yaml")])], C.SEQ_INPUTS + ["config.yaml"]))
    for fmt in C.FORMATS:
        files = dict(C.format_files(fmt))
        targets = C.format_members(fmt) + (["model.npz"] if fmt in ("cliff", "4dhumans", "bedlam", "gvhmr", "slahmr")
                                           else [])
        out.append(Base(f"import-{fmt}", files, targets,
                        [("import", C.import_args(fmt), ["out"], [C.check_files("out/meta.yaml"), C.check_seq("out")])],
                        ["src", "model.npz"]))
    return out


# =================================================================================================
# Mutations
# =================================================================================================
JUNK = [None, "junk", -1, 0, 1e300, float("nan"), float("inf"), [], {}, [1, 2, 3], True, 2**70, "../../x",
        np.zeros((2, 2)), np.array(["a", "b"]), np.full(3, np.inf), np.zeros((0, 3)), np.int64(-5)]
DTYPES = ["int8", "uint8", "int32", "uint64", "float16", "float64", "complex64", "bool", "U4", "datetime64[s]"]


def mutate_bytes(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    n = len(data)
    op = rng.choice(["flip", "truncate", "insert", "zero", "duplicate", "append", "empty"],
                    p=[0.35, 0.2, 0.1, 0.1, 0.1, 0.1, 0.05])
    if n == 0 or op == "empty":
        return "bytes:empty", b""
    b = bytearray(data)
    if op == "flip":
        for _ in range(int(rng.integers(1, 9))):
            i = int(rng.integers(0, n))
            b[i] ^= 1 << int(rng.integers(0, 8)) if rng.random() < 0.5 else int(rng.integers(1, 256))
        return "bytes:flip", bytes(b)
    i = int(rng.integers(0, n))
    if op == "truncate":
        return "bytes:truncate", bytes(b[:i])
    j = min(n, i + int(rng.integers(1, 256)))
    if op == "insert":
        return "bytes:insert", bytes(b[:i]) + rng.bytes(int(rng.integers(1, 64))) + bytes(b[i:])
    if op == "zero":
        b[i:j] = bytes(j - i)
        return "bytes:zero", bytes(b)
    if op == "duplicate":
        return "bytes:duplicate", bytes(b[:j]) + bytes(b[i:j]) + bytes(b[j:])
    return "bytes:append", bytes(b) + rng.bytes(int(rng.integers(1, 512)))


def _npy_load(raw: bytes) -> np.ndarray:
    from rotavat_cli import unpickle

    return unpickle.load_npy_bytes(raw, "member.npy")


def _npy_save(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=arr.dtype.hasobject)
    return buf.getvalue()


def mutate_array(arr: np.ndarray, rng: np.random.Generator) -> tuple[str, Any]:
    op = rng.choice(["dtype", "shape", "value", "replace"])
    if op == "dtype":
        dt = str(rng.choice(DTYPES))
        try:
            with np.errstate(all="ignore"):
                return f"array:dtype-{dt}", arr.astype(dt)
        except (TypeError, ValueError):
            return "array:dtype-U4", arr.astype("U4")
    if op == "shape":
        choice = rng.choice(["flatten", "add-axis", "drop-people", "repeat-people", "last-axis-1", "transpose",
                             "scalar"])
        if choice == "flatten":
            return "array:shape-flatten", arr.reshape(-1)
        if choice == "add-axis":
            return "array:shape-add-axis", arr[None]
        if choice == "drop-people" and arr.ndim:
            return "array:shape-drop-people", arr[: max(0, len(arr) - 1)]
        if choice == "repeat-people" and arr.ndim:
            return "array:shape-repeat-people", np.concatenate([arr, arr[:1]]) if len(arr) else arr
        if choice == "last-axis-1" and arr.ndim:
            return "array:shape-last-axis-1", arr[..., :1]
        if choice == "transpose" and arr.ndim > 1:
            return "array:shape-transpose", np.ascontiguousarray(arr.T)
        return "array:shape-scalar", arr.reshape(-1)[:1].reshape(()) if arr.size else np.float64(1.0)
    if op == "value" and arr.size and arr.dtype.kind in "fiu":
        out = arr.copy()
        value = rng.choice(["nan", "inf", "-1", "0", "huge"])
        v = {"nan": np.nan, "inf": np.inf, "-1": -1, "0": 0, "huge": 1e30}[value]
        if out.dtype.kind != "f" and value in ("nan", "inf", "huge"):
            v = np.iinfo(out.dtype).max
        flat = out.reshape(-1)
        idx = rng.integers(0, flat.size, size=int(rng.integers(1, 4)))
        with np.errstate(all="ignore"):
            flat[idx] = v
        return f"array:value-{value}", out
    junk = JUNK[int(rng.integers(0, len(JUNK)))]
    return "array:replace", junk


def _paths(obj: Any, depth: int = 0, prefix: tuple = ()) -> list[tuple]:
    """(container path) of every node of a nested dict/list/tuple tree (capped depth and count)."""
    out = [prefix]
    if depth > 6 or len(out) > 2000:
        return out
    if isinstance(obj, dict):
        for k, v in list(obj.items())[:200]:
            out += _paths(v, depth + 1, prefix + (k,))
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj[:50]):
            out += _paths(v, depth + 1, prefix + (i,))
    elif isinstance(obj, np.ndarray) and obj.dtype == object and obj.shape == ():
        out += _paths(obj.item(), depth + 1, prefix + ("<item>",))
    return out


def _get(obj: Any, path: tuple) -> Any:
    for k in path:
        obj = obj.item() if k == "<item>" else obj[k]
    return obj


def _set_path(obj: Any, path: tuple, value: Any, delete: bool = False, rename: Any = None) -> Any:
    """A copy of ``obj`` with the node at ``path`` replaced, deleted or (dict key) renamed."""
    if not path:
        return value
    head, rest = path[0], path[1:]
    if head == "<item>":
        new = np.empty((), dtype=object)
        new[()] = _set_path(obj.item(), rest, value, delete, rename)
        return new
    if isinstance(obj, dict):
        new = dict(obj)
        if not rest:
            if delete:
                new.pop(head, None)
            elif rename is not None:
                new[rename] = new.pop(head)
            else:
                new[head] = value
            return new
        new[head] = _set_path(obj[head], rest, value, delete, rename)
        return new
    seq = list(obj)
    if not rest:
        if delete:
            del seq[head]
        else:
            seq[head] = value
    else:
        seq[head] = _set_path(seq[head], rest, value, delete, rename)
    return tuple(seq) if isinstance(obj, tuple) else seq


def mutate_tree(obj: Any, rng: np.random.Generator) -> tuple[str, Any]:
    paths = [p for p in _paths(obj) if p]
    if not paths:
        return "tree:replace-root", JUNK[int(rng.integers(0, len(JUNK)))]
    path = paths[int(rng.integers(0, len(paths)))]
    node = _get(obj, path)
    parent = _get(obj, path[:-1]) if path[:-1] else obj
    op = rng.choice(["delete", "rename", "junk", "array"])
    if op == "array" and isinstance(node, np.ndarray) and node.dtype != object:
        name, new = mutate_array(node, rng)
        return f"tree:{name}", _set_path(obj, path, new)
    if op == "delete" and isinstance(parent, (dict, list)) and path[-1] != "<item>":
        return "tree:delete", _set_path(obj, path, None, delete=True)
    if op == "rename" and isinstance(parent, dict):
        new_key = rng.choice([str(path[-1]).upper(), f"{path[-1]}_x", "../evil", "", 7])
        return "tree:rename-key", _set_path(obj, path, None, rename=new_key.item() if hasattr(new_key, "item") else new_key)
    return "tree:junk", _set_path(obj, path, JUNK[int(rng.integers(0, len(JUNK)))])


def mutate_npz(data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            members = [(n, z.read(n)) for n in z.namelist()]
    except Exception:  # noqa: BLE001 - not a readable zip: mutate bytes
        return None
    if not members:
        return None
    op = rng.choice(["delete", "duplicate", "rename", "content", "member-bytes"], p=[0.15, 0.1, 0.15, 0.45, 0.15])
    k = int(rng.integers(0, len(members)))
    name = "npz:" + str(op)
    if op == "delete":
        del members[k]
    elif op == "duplicate":
        other = members[int(rng.integers(0, len(members)))]
        members.append((members[k][0], other[1]))
    elif op == "rename":
        old = members[k][0]
        stem = old[:-4] if old.endswith(".npy") else old
        new = str(rng.choice([stem.upper(), stem + "_x", "../../" + stem, "/tmp/" + stem, stem.replace("_", ""),
                              members[int(rng.integers(0, len(members)))][0][:-4], "person_ids", "K"]))
        members[k] = (new + ".npy", members[k][1])
    elif op == "member-bytes":
        sub, raw = mutate_bytes(members[k][1], rng)
        members[k] = (members[k][0], raw)
        name += "-" + sub.split(":")[1]
    else:
        try:
            arr = _npy_load(members[k][1])
        except Exception:  # noqa: BLE001
            return None
        if arr.dtype == object:
            sub, new = mutate_tree(arr, rng)
            if not isinstance(new, np.ndarray):
                new = C._obj(new)
        else:
            sub, new = mutate_array(arr, rng)
        try:
            raw = _npy_save(np.asarray(new) if not isinstance(new, np.ndarray) else new)
        except Exception:  # noqa: BLE001
            return None
        members[k] = (members[k][0], raw)
        name = f"npz:{sub}"
    buf = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if rng.random() < 0.3 else zipfile.ZIP_STORED
    with zipfile.ZipFile(buf, "w", method) as z, _quiet_zip():
        for n, raw in members:
            z.writestr(n, raw)
    return name, buf.getvalue()


class _quiet_zip:
    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore")  # "Duplicate name" warnings

    def __exit__(self, *exc):
        self._w.__exit__(*exc)


def mutate_pickle(data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    from rotavat_cli import unpickle

    compressed = data[:1] == b"x"
    try:
        raw = zlib.decompress(data) if compressed else data
        obj = unpickle.loads(raw, "x.pkl")
    except Exception:  # noqa: BLE001
        return None
    name, new = mutate_tree(obj, rng)
    try:
        if compressed or rng.random() < 0.3:
            from _format_fixtures import joblib_bytes

            out = joblib_bytes(new, compress=3 if compressed else 0, protocol=int(rng.integers(2, 5)))
        else:
            out = pickle.dumps(new, protocol=int(rng.integers(0, pickle.HIGHEST_PROTOCOL + 1)))
    except Exception:  # noqa: BLE001
        return None
    return "pickle:" + name.split(":", 1)[1], out


def mutate_yaml(data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    import yaml

    try:
        obj = yaml.safe_load(data)
    except yaml.YAMLError:
        return None
    if not isinstance(obj, dict):
        return None
    op = rng.choice(["tree", "add-key", "tag", "anchor"], p=[0.7, 0.1, 0.1, 0.1])
    if op == "add-key":
        obj = dict(obj)
        obj[str(rng.choice(["extra", "focal_kind", "source", "image_size", "fit", "align"]))] = \
            JUNK[int(rng.integers(0, 13))]
        name = "yaml:add-key"
    elif op == "tag":
        key = list(obj)[int(rng.integers(0, len(obj)))]
        text = data.decode("utf-8", "replace") + f"\n{key}_tagged: !!{rng.choice(['binary AAAA', 'set {a: null}', 'timestamp 2001-12-14', 'float .nan'])}\n"
        return "yaml:tag", text.encode()
    elif op == "anchor":
        text = "base: &b [1, 2, 3]\n" + data.decode("utf-8", "replace") + "\nrefs: [*b, *b, *b]\n"
        return "yaml:anchor", text.encode()
    else:
        name, obj = mutate_tree(obj, rng)
        name = "yaml:" + name.split(":", 1)[1]

    def plain(x: Any) -> Any:
        if isinstance(x, np.ndarray):
            return x.tolist()
        if isinstance(x, np.generic):
            return x.item()
        if isinstance(x, dict):
            return {str(k) if not isinstance(k, (int, float, bool)) else k: plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        return x

    try:
        return name, yaml.safe_dump(plain(obj)).encode()
    except yaml.YAMLError:
        return None


_NUMBER = re.compile(rb"-?\d+(\.\d+)?(e[-+]?\d+)?")


def mutate_obj(data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    lines = data.split(b"\n")
    op = rng.choice(["number", "delete-lines", "bad-face", "duplicate-lines"])
    if op == "number":
        i = int(rng.integers(0, len(lines)))
        repl = bytes(rng.choice([b"nan", b"inf", b"-inf", b"1e308", b"x", b"", b"99999999", b"-1", b"0"]))
        lines[i] = _NUMBER.sub(lambda m: repl if rng.random() < 0.5 else m.group(0), lines[i], count=3)
        return "obj:number", b"\n".join(lines)
    if op == "delete-lines":
        i = int(rng.integers(0, len(lines)))
        del lines[i: i + int(rng.integers(1, 20))]
        return "obj:delete-lines", b"\n".join(lines)
    if op == "bad-face":
        lines.append(bytes(rng.choice([b"f 1 2 99999", b"f 0 0 0", b"f -999 1 2", b"f 1", b"f a b c"])))
        return "obj:bad-face", b"\n".join(lines)
    i = int(rng.integers(0, len(lines)))
    return "obj:duplicate-lines", b"\n".join(lines[:i] + lines[i: i + 10] * 2 + lines[i + 10:])


def mutate_torch(data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    """A torch.save file (zip archive or legacy stream) loaded, its tree damaged, re-saved by the test
    writers with every numeric array a torch tensor (zip or legacy stream at random)."""
    from rotavat_cli.unpickle import load_torch_bytes

    try:
        obj = load_torch_bytes(data, "x.pt")
    except Exception:  # noqa: BLE001
        return None
    name, new = mutate_tree(obj, rng)
    legacy = rng.random() < 0.2
    try:
        tensors = C._tensors(new)
        out = C.T.legacy_bytes(tensors) if legacy else C.T.torch_zip_bytes(tensors, name="hmr4d_results")
    except Exception:  # noqa: BLE001
        return None
    return ("torch-legacy:" if legacy else "torch:") + name.split(":", 1)[1], out


def mutate_npy_dict(rel: str, data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    """An ``np.save`` of a dict (TRAM: of torch tensors) loaded, its tree damaged, re-saved the same way."""
    try:
        obj = C._load_any_npy(data)
    except Exception:  # noqa: BLE001
        return None
    if not isinstance(obj, dict):
        return None
    name, new = mutate_tree(obj, rng)
    try:
        return "npy:" + name.split(":", 1)[1], C.npy_tensors_bytes(C._tensors(new) if "/hps/" in rel else new)
    except Exception:  # noqa: BLE001
        return None


def mutate_json(data: bytes, rng: np.random.Generator) -> tuple[str, bytes] | None:
    try:
        obj = json.loads(data)
    except ValueError:
        return None
    if rng.random() < 0.15:
        token = str(rng.choice(["NaN", "Infinity", "-Infinity", "1e400", "-1", "18446744073709551616", "[[[[[]]]]]"]))
        text = data.decode("utf-8", "replace")
        spots = [m.start() for m in re.finditer(r"(?<=: )-?\d+", text)]
        if spots:
            i = spots[int(rng.integers(0, len(spots)))]
            end = re.match(r"-?\d+", text[i:]).end()
            return "json:token", (text[:i] + token + text[i + end:]).encode()
    name, new = mutate_tree(obj, rng)

    def plain(x: Any) -> Any:
        if isinstance(x, np.ndarray):
            return x.tolist()
        if isinstance(x, np.generic):
            return x.item()
        if isinstance(x, dict):
            return {str(k): plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        return x

    try:
        return "json:" + name.split(":", 1)[1], json.dumps(plain(new)).encode()
    except (TypeError, ValueError):
        return None


def mutate_file(rel: str, data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """A damaged copy of ``data`` (the file ``rel``): structural where the format allows, else bytes."""
    structural = None
    if rng.random() < 0.7:
        try:
            if rel.endswith((".pt", ".pth")) and rng.random() < 0.6:
                structural = mutate_torch(data, rng)
            elif rel.endswith(".npz") or data[:2] == b"PK":
                structural = mutate_npz(data, rng)
            elif rel.endswith(".npy"):
                structural = mutate_npy_dict(rel, data, rng)
            elif rel.endswith((".pkl", ".pk")):
                structural = mutate_pickle(data, rng)
            elif rel.endswith(".yaml"):
                structural = mutate_yaml(data, rng)
            elif rel.endswith(".json"):
                structural = mutate_json(data, rng)
            elif rel.endswith(".obj"):
                structural = mutate_obj(data, rng)
        except Exception:  # noqa: BLE001 - a mutation numpy/yaml cannot express: damage the bytes instead
            structural = None
    return structural or mutate_bytes(data, rng)


# =================================================================================================
# The campaign
# =================================================================================================
def make_case(i: int, seed: int, all_bases: list[Base]) -> C.Case:
    """Iteration ``i``'s case (its own generator: reproducible on its own)."""
    rng = np.random.default_rng([seed, i])
    base = all_bases[int(rng.integers(0, len(all_bases)))]
    target = base.targets[int(rng.integers(0, len(base.targets)))]
    files = dict(base.files)
    original = files[target]
    if callable(original):
        original = original(Path("/nonexistent"))
    if isinstance(original, str):
        original = original.encode()
    mutation, damaged = mutate_file(target, original, rng)
    files[target] = damaged
    cmd_name, args, outputs, checks = base.commands[int(rng.integers(0, len(base.commands)))]
    if damaged == original:
        mutation += "(no-op)"
    names = sorted({Path(target).name, Path(target).stem, Path(target).parent.name, base.inputs[0]} - {""})
    return C.Case(f"fuzz/{i}/{base.name}/{cmd_name}/{mutation}", f"{base.name}:{mutation.split(':')[0]}",
                  list(args), files, "either", list(base.inputs), list(outputs), names, checks=list(checks),
                  timeout_s=30.0, note=f"damaged {target}")


def _set_memory_guard() -> None:
    import resource

    try:
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = H.ADDRESS_SPACE_LIMIT if hard == resource.RLIM_INFINITY else min(hard, H.ADDRESS_SPACE_LIMIT)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ValueError, OSError):
        pass


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--iterations", type=int, default=DEFAULT_ITERATIONS, help="runs (default %(default)s)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--memory-every", type=int, default=25,
                        help="every N-th run is a real process with its peak RSS measured (0 = never)")
    parser.add_argument("--only", type=int, default=None, help="run just this iteration")
    parser.add_argument("--keep", type=Path, default=None, help="with --only: keep the case folder here")
    parser.add_argument("--report", type=Path, default=None, help="write every run record as JSON lines")
    parser.add_argument("--corpus", action="store_true", help="also run the fixed corpus first")
    parser.add_argument("--no-slow", action="store_true",
                        help="skip the slow measured cases (corpus.slow_cases: memory and time bombs) run first")
    parser.add_argument("--check-bomb", action="store_true",
                        help="rebuild the stored 1.2 GB bz2 bomb stream and compare (slow: 5 s)")
    args = parser.parse_args(argv)
    _set_memory_guard()

    if args.check_bomb:
        header = C.npy_header("<f4", C._BOMB_SHAPE)
        data, crc = C._bz2_zeros_stream(header, int(np.prod(C._BOMB_SHAPE)) * 4)
        same = data == __import__("base64").b64decode(C._BOMB_B64) and crc == C._BOMB_CRC
        print("stored bomb stream matches its recipe" if same else "stored bomb stream DIFFERS from its recipe")
        if not same:
            return 1

    all_bases = bases()
    cases: list[C.Case] = []
    if args.corpus:
        cases += C.all_cases()
    if not args.no_slow and args.only is None:
        cases += C.slow_cases()
    iterations = [args.only] if args.only is not None else range(args.iterations)
    cases += [make_case(i, args.seed, all_bases) for i in iterations]

    records: list[H.RunRecord] = []
    t0 = time.monotonic()
    report = open(args.report, "w", encoding="utf-8") if args.report else None
    tmp_root = Path(tempfile.mkdtemp(prefix="rotavat-fuzz-"))
    try:
        for n, case in enumerate(cases):
            if case.id.startswith("fuzz/"):
                sub = args.memory_every > 0 and n % args.memory_every == args.memory_every - 1
            else:
                sub = case.subprocess
            folder = (args.keep if (args.keep and args.only is not None) else tmp_root / f"c{n}")
            if folder.exists():
                H._unlock(folder)
                shutil.rmtree(folder)
            rec = H.run_case(case, folder, subprocess_mode=sub)
            records.append(rec)
            if report:
                report.write(json.dumps(rec.as_dict()) + "\n")
                report.flush()
            if not rec.ok:
                print(rec.describe(), flush=True)
            if not (args.keep and args.only is not None):
                H._unlock(folder)
                shutil.rmtree(folder, ignore_errors=True)
            if (n + 1) % 100 == 0:
                bad = sum(not r.ok for r in records)
                print(f"... {n + 1}/{len(cases)} runs, {bad} with violations, {time.monotonic() - t0:.0f} s",
                      flush=True)
    finally:
        if report:
            report.close()
        shutil.rmtree(tmp_root, ignore_errors=True)
    return summarize(records, time.monotonic() - t0)


def summarize(records: list[H.RunRecord], seconds: float) -> int:
    import resource

    by_cls: dict[str, list[H.RunRecord]] = defaultdict(list)
    for r in records:
        by_cls[r.cls].append(r)
    width = max([len(k) for k in by_cls] + [5])
    print()
    print(f"{'class':{width}}  cases  exit0  exit2  other  violations")
    for cls in sorted(by_cls):
        rs = by_cls[cls]
        codes = Counter(r.exit_code for r in rs)
        other = len(rs) - codes[0] - codes[2]
        print(f"{cls:{width}}  {len(rs):5d}  {codes[0]:5d}  {codes[2]:5d}  {other:5d}  {sum(not r.ok for r in rs):10d}")
    total_bad = [r for r in records if not r.ok]
    print(f"{'total':{width}}  {len(records):5d}  {'':5}  {'':5}  {'':5}  {len(total_bad):10d}")
    rules = Counter(rule for r in total_bad for rule, _ in r.violations)
    measured = [r.peak_rss_mb for r in records if r.peak_rss_mb is not None]
    print(f"\n{len(records)} runs in {seconds:.0f} s; {len(measured)} measured as processes"
          + (f" (peak RSS max {max(measured):.0f} MB, median {np.median(measured):.0f} MB)" if measured else "")
          + f"; this process peaked at {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    if rules:
        print("violations by rule: " + ", ".join(f"{k} {v}" for k, v in sorted(rules.items())))
        print("\nfirst violations (replay one with --only I --keep DIR):")
        seen = set()
        for r in total_bad:
            key = (r.cls, tuple(rule for rule, _ in r.violations))
            if key in seen:
                continue
            seen.add(key)
            print(r.describe())
    else:
        print("no rule broken")
    return 1 if total_bad else 0


if __name__ == "__main__":
    sys.exit(main())
