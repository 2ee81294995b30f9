"""Batch options, the run plan (one job per sequence) and the completion markers that make runs resumable."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from ..geometry.camera import camera_from_yaml_dict
from ..settings.config import default_config
from ..errors import InputError, input_errors
from ..metrics.evaluate import MATCHES
from ..settings.option_rules import Rule, check_fields
from ..plain import to_plain
from ..render.sequences import FigureOptions
from ..view.recording import ViewOptions
from ..view.writer import require_rerun
from ..files.yaml_io import read_yaml
from .discover import discover_sequences, fingerprint, frames_hint

__all__ = ["STEPS", "MARKER", "MARKER_VERSION", "ALIGN_STAGING", "OUTPUTS", "BatchOptions", "parse_steps",
           "make_plan", "completed_marker"]

STEPS = ("calibrate", "align", "eval", "render", "view")
EXECUTORS = ("local", "dask")
MARKER = ".rotavat-complete"
MARKER_VERSION = 1
ALIGN_STAGING = ".aligned.chunks"  # align chunks' staging (aligned/ and render/ are staged beside them by staged_directory)
OUTPUTS = {"calibrate": "camera.yaml", "align": "aligned/people.csv", "eval": "eval/metrics.json", "render": "render",
           "view": "view.rrd"}


@dataclass(frozen=True)
class BatchOptions:
    """What ``rotavat batch`` can vary; ``config`` is a merged configuration (calibrate/align/eval/render)."""

    steps: tuple[str, ...] = field(default_factory=lambda: parse_steps(default_config()["batch"]["steps"]))  # view: when asked
    gt_root: Path | None = None
    fmt: str | None = None  # importer format of the sequences (--from)
    gt_fmt: str | None = None  # importer format of the ground truth under gt_root (--gt-from)
    image_size: tuple[int, int] | None = None  # --from: original image size
    smpl_model: Path | None = None  # --from: body model for parameter-only formats
    executor: str = "local"  # local | dask
    jobs: int = 0  # 0: one per core
    scheduler: str | None = None  # dask: address of an existing scheduler; None = a LocalCluster
    chunk_frames: int = 100
    force: bool = False
    camera: Path | None = None  # --camera: a camera.yaml for every sequence (the calibrate step copies it, fits none)
    accept_camera: bool = False  # --accept-camera: use cameras whose calibration is implausible (with a warning)
    config: dict = field(default_factory=default_config)

    RULES: ClassVar[dict[str, Rule]] = {  # the ``batch`` keys' bounds and names (rotavat_cli/settings/option_rules.py)
        "executor": Rule(names=EXECUTORS), "jobs": Rule(low=0), "chunk_frames": Rule(low=1),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.RULES)

    @classmethod
    def from_config(cls, config: dict, **fields: Any) -> "BatchOptions":
        """Options from a merged config's ``batch`` section, overridden by ``fields``."""
        section = config["batch"]
        base = {"steps": parse_steps(section["steps"]), "executor": section["executor"], "jobs": int(section["jobs"]),
                "scheduler": section["scheduler"], "chunk_frames": int(section["chunk_frames"]), "config": config}
        return cls(**{**base, **fields})



def parse_steps(text: str | Iterable[str]) -> tuple[str, ...]:
    """'align,calibrate' -> ('calibrate', 'align'): known steps, always run in pipeline order."""
    names = [s.strip().lower() for s in (text.split(",") if isinstance(text, str) else text) if s.strip()]
    unknown = [s for s in names if s not in STEPS]
    if unknown or not names:
        raise InputError(f"--steps: unknown step(s) {', '.join(unknown) or '(none)'}; choose from {','.join(STEPS)}")
    return tuple(s for s in STEPS if s in names)



def _digest(value: Any) -> str:
    """Stable digest of plain data."""
    return hashlib.sha256(json.dumps(to_plain(value), sort_keys=True).encode()).hexdigest()[:16]


def _step_digests(plan: dict) -> dict[str, str]:
    """Per step, a digest of every option its outputs depend on (a changed option redoes the sequence).

    ``--camera FILE`` counts by its content; ``--accept-camera`` does not (it changes whether a sequence
    runs, not its outputs: a sequence refused without it has no marker and runs again).
    """
    cfg, imp = plan["config"], plan["import"]
    align = {k: v for k, v in cfg["align"].items() if k != "jobs"}  # how many processes does not change the result
    camera = [plan["camera"]["yaml"]] if plan.get("camera") else []  # absent: the digests of earlier versions
    return {"calibrate": _digest([cfg["calibrate"], imp, *camera]), "align": _digest([cfg["calibrate"], align, imp, *camera]),
            "eval": _digest([cfg["eval"], imp, plan["gt_root"]]), "render": _digest([cfg["render"], imp, *camera]),
            "view": _digest([cfg["view"], cfg["render"], imp, plan["gt_root"], *camera])}


def completed_marker(job: dict, plan: dict) -> dict | None:
    """The marker of ``job`` when its outputs are complete for ``plan``, else None (run it).

    Complete: the marker exists (it is written last), lists every requested step with the same
    options, the inputs' fingerprints (every file's name, size and mtime) are those it recorded, and
    each step's main output exists. The marker's own mtime is never compared with the inputs': an
    input stamped in the future (a copy from a machine whose clock is ahead) would make a finished
    sequence run again until the clock caught up.
    """
    out = Path(job["out"])
    try:
        marker = json.loads((out / MARKER).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(marker, dict) or marker.get("version") != MARKER_VERSION:
        return None
    options = marker.get("options") or {}
    if any(step not in marker.get("steps", []) or options.get(step) != plan["digests"][step] for step in plan["steps"]):
        return None
    inputs = marker.get("inputs") or {}
    if any(inputs.get(key) != value for key, value in job["inputs"].items()):
        return None
    if not all((out / OUTPUTS[step]).exists() for step in plan["steps"]):
        return None
    return marker



def make_plan(root: Path, out: Path, options: BatchOptions) -> tuple[dict, list[dict]]:
    """Validate the options, find the sequences, and build the plan and one job per sequence."""
    if options.executor not in EXECUTORS:
        raise InputError(f"--executor must be one of {', '.join(EXECUTORS)}, got {options.executor!r}")
    if options.jobs < 0 or options.chunk_frames < 1:
        raise InputError(f"--jobs must be >= 0 and --chunk-frames >= 1, got {options.jobs} and {options.chunk_frames}")
    if options.config["eval"]["match"] not in MATCHES:
        raise InputError(f"eval.match must be one of {', '.join(MATCHES)}, got {options.config['eval']['match']!r}")
    steps = parse_steps(options.steps)
    if "eval" in steps and options.gt_root is None:
        raise InputError("the eval step needs --gt-root (ground truth mirroring ROOT's tree)")
    gt_root = Path(options.gt_root).resolve() if options.gt_root is not None else None
    if gt_root is not None and not gt_root.is_dir():
        raise InputError(f"{options.gt_root}: no such directory (--gt-root)")
    if not root.is_dir():
        raise InputError(f"{root}: no such directory")
    if out.resolve() == root.resolve() or (gt_root is not None and out.resolve() == gt_root):
        raise InputError(f"{out}: the output folder must differ from ROOT and --gt-root")
    if "render" in steps:
        with input_errors("render"):
            FigureOptions.from_config(options.config["render"])
    if "view" in steps:
        with input_errors("view"):
            ViewOptions.from_config(options.config["view"], options.config["render"])
        require_rerun()  # before any work: one line naming the pip command
    found = discover_sequences(root, options.fmt, exclude=[out] + ([gt_root] if gt_root else []))
    gt_sources = dict(discover_sequences(gt_root, options.gt_fmt, exclude=[out])) \
        if options.gt_fmt and gt_root is not None and "eval" in steps else {}
    if not found:
        what = f"{options.fmt} outputs" if options.fmt else "sequences (folders of *.npz frames or of OBJ frame folders)"
        raise InputError(f"{root}: no {what} found")
    camera = None
    if options.camera is not None:  # read once here: a missing or unreadable file is a usage error (exit 2)
        path = Path(options.camera).resolve()
        camera = {"path": str(path), "yaml": read_yaml(path)}
        if "image_size" in camera["yaml"]:  # else each sequence's image size completes it (checked per sequence)
            with input_errors(f"{options.camera} (--camera)"):
                camera_from_yaml_dict(camera["yaml"])
    plan = {"steps": list(steps), "config": options.config, "chunk_frames": options.chunk_frames,
            "gt_root": str(gt_root) if gt_root else None, "root": str(root), "out": str(out),
            "camera": camera, "accept_camera": bool(options.accept_camera),
            "import": {"format": options.fmt, "gt_format": options.gt_fmt,
                       "image_size": list(options.image_size) if options.image_size else None,
                       "smpl_model": str(Path(options.smpl_model).resolve()) if options.smpl_model else None}}
    plan["digests"] = _step_digests(plan)
    jobs = []
    out_abs = out.resolve()
    for index, (rel, path) in enumerate(found):
        target = out_abs / rel
        gt = gt_root / rel if gt_root is not None and "eval" in steps else None
        if gt is not None and options.gt_fmt:  # the GT source found by its importer; imported into OUT/<rel>/gt
            gt = gt_sources.get(rel, gt)
        job = {"rel": rel, "index": index, "source": str(path.resolve()),
               "seq": str(target / "input") if options.fmt else str(path.resolve()), "out": str(target),
               "gt": str(target / "gt") if gt is not None and options.gt_fmt else (str(gt) if gt is not None else None),
               "gt_source": str(gt) if gt is not None else None,
               "frames_hint": None if options.fmt else frames_hint(path)}
        inputs = {"sequence": fingerprint(path, exclude=[out_abs] + ([gt_root] if gt_root else []))}
        if gt is not None:
            inputs["gt"] = fingerprint(gt) if gt.exists() else {"files": 0, "bytes": 0, "newest_mtime_ns": 0, "digest": "missing"}
        job["inputs"] = inputs
        jobs.append(job)
    return plan, jobs

