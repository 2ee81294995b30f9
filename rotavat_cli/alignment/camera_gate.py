"""Never use an absurd camera silently: one gate for every command that uses a camera.

A calibration checks its camera for plausibility and lists what failed in its ``fit:`` block,
``implausible: [...]`` (absent or empty: plausible; a camera.yaml without a ``fit:`` block, such
as ground truth or a hand-written camera, is never implausible). ``rotavat align``, ``render`` and
``batch`` pass every camera they use through :func:`check_fit`:

- plausible: used silently;
- implausible and the user gave ``--accept-camera``: used, with a warning naming the findings;
  what ``align`` writes then records the consent (``fit.accepted: true`` in the aligned output's
  camera.yaml, beside the findings), so the output is not refused again downstream;
- implausible and recorded as accepted (``fit.accepted: true``): used, with the same warning;
- otherwise refused: :class:`ImplausibleCameraError` (an InputError, exit 2), one line naming the
  camera, the findings, and what to give instead, as commands with the user's paths
  (:class:`Remedies`, built by :func:`align_remedies`, :func:`render_remedies`, :func:`batch_remedies`).

>>> fit = {"implausible": ["camera height 0.11 m is under 0.3 m"]}
>>> implausible_findings(fit), implausible_findings({}), implausible_findings(None)
(('camera height 0.11 m is under 0.3 m',), (), ())
>>> check_fit("cam.yaml", {"implausible": []}, accept=False, remedies=align_remedies("seq")) is None
True
>>> check_fit("cam.yaml", fit, accept=True, remedies=align_remedies("seq"))
'cam.yaml: implausible camera (camera height 0.11 m is under 0.3 m), used anyway (--accept-camera)'
>>> accepted_fit(fit)
{'implausible': ['camera height 0.11 m is under 0.3 m'], 'accepted': True}
>>> try:
...     check_fit("cam.yaml", fit, accept=False, remedies=align_remedies("seq"))
... except ImplausibleCameraError as exc:  # one line; shown here cut at each remedy
...     print(str(exc).replace("; give", ";\\ngive").replace(", or ", ",\\nor "))
cam.yaml: implausible camera (camera height 0.11 m is under 0.3 m);
give what you know: rotavat calibrate seq --focal PX --camera-height M [--pitch DEG] (then rotavat align seq),
or rotavat align seq --camera FILE (a camera.yaml you wrote: docs/conventions.md#camerayaml),
or rotavat align seq --accept-camera to use it anyway
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..files.outputs import imported_output
from .camera_choice import CALIBRATED, AlignCamera

__all__ = ["IMPLAUSIBLE", "ACCEPTED", "ACCEPT_FLAG", "CAMERA_DOC", "KNOWN_FLAGS", "OTHER_CAUSES", "ImplausibleCameraError",
           "Remedies", "flags_not_given", "what_to_give",
           "implausible_findings", "is_accepted", "accepted_fit", "check_fit", "check_align_camera", "camera_what",
           "reader_flags", "align_remedies", "render_remedies", "batch_remedies"]

IMPLAUSIBLE, ACCEPTED = "implausible", "accepted"  # keys of camera.yaml's fit block
ACCEPT_FLAG = "--accept-camera"
CAMERA_DOC = "docs/conventions.md#camerayaml"  # where camera.yaml's schema is written down
# What a user may know of a camera (calibrate's and batch's flags), each with the fit key that records it given
# (fit.fixed[key] == "given" or "declared").
_KNOWN = (("focal_px", "--focal PX"), ("height_m", "--camera-height M"), ("pitch_deg", "[--pitch DEG]"))
KNOWN_FLAGS = " ".join(flag for _, flag in _KNOWN)
# What else makes a camera wrong once everything a user may know of it was given: the people, not the camera.
OTHER_CAUSES = ("the people do not fit the model: people cut by the image border, not standing (sitting, "
                "jumping), on steps or uneven ground, or a mismatched body model; check calibrate's notes and "
                "warnings, people.csv's flags and rotavat render's figure")


class ImplausibleCameraError(InputError):
    """A camera whose fit lists implausible findings, used without ``--accept-camera`` (exit 2)."""


def implausible_findings(fit: Mapping | None) -> tuple[str, ...]:
    """The fit block's implausible findings: () when it has none (no fit block, the key absent or empty).

    A hand-written single string counts as one finding; blank entries are dropped.
    """
    if not isinstance(fit, Mapping):
        return ()
    value = fit.get(IMPLAUSIBLE)
    if not value:
        return ()
    items = [value] if isinstance(value, str) else value if isinstance(value, (list, tuple)) else [value]
    return tuple(" ".join(str(item).split()) for item in items if str(item).strip())


def is_accepted(fit: Mapping | None) -> bool:
    """The fit block records that a user accepted its camera (``accepted: true``, written by align)."""
    return isinstance(fit, Mapping) and fit.get(ACCEPTED) is True


def accepted_fit(fit: Mapping | None) -> dict:
    """The fit block to write with a camera used under ``--accept-camera``: the same, plus ``accepted: true``
    when it lists implausible findings (a plausible camera's block is unchanged)."""
    block = dict(fit or {})
    if implausible_findings(block):
        block[ACCEPTED] = True
    return block


@dataclass(frozen=True)
class Remedies:
    """What a refusal suggests, each a command with the user's paths (placeholders PX, M, DEG, FILE aside).

    The message reads: ``give what you know: {calibrate} {KNOWN_FLAGS} ({then}), or {camera}, or
    {accept} to use it anyway``; ``camera`` may be empty (no camera file can stand in).
    """

    calibrate: str  # the command that fits the camera again, to which the KNOWN_FLAGS not yet given are added
    then: str  # what to run or know after it
    camera: str  # how to give a camera.yaml instead, with CAMERA_DOC; "" when none can be given here
    accept: str  # the command (or flag) that uses the camera anyway


def _join(*parts: object) -> str:
    """A command line, each part quoted for a POSIX shell when needed (paths with spaces)."""
    return " ".join(shlex.quote(str(p)) for p in parts if p is not None and str(p) != "")


def reader_flags(fmt: str | None, image_size: tuple[int, int] | None = None,
                 smpl_model: str | Path | None = None) -> tuple[str, ...]:
    """The flags that read an HPS tool's output (``--from FMT [--image-size W H] [--smpl-model FILE]``), () for a
    contract sequence: remedies repeat them so their commands read the same input."""
    if not fmt:
        return ()
    return ("--from", fmt, *(("--image-size", str(image_size[0]), str(image_size[1])) if image_size else ()),
            *(("--smpl-model", str(smpl_model)) if smpl_model else ()))


def align_remedies(seq: str | Path, out: str | Path | None = None, reader_flags: tuple[str, ...] = (),
                   config: str | Path | None = None) -> Remedies:
    """``rotavat align``'s: calibrate SEQ with what you know, then align; or align --camera FILE; or accept.

    ``reader_flags``: ``--from FMT [--image-size W H] [--smpl-model FILE]`` when SEQ is an HPS tool's
    output (calibrate then writes its camera.yaml beside SEQ, and align reads it with --camera).
    """
    extra = (*reader_flags, *(("--config", config) if config else ()))
    align = _join("rotavat", "align", seq, *extra, *(("--out", out) if out else ()))
    if reader_flags:  # an HPS tool's output: calibrate needs --out, and align reads that file
        camera_file = imported_output(seq, "_camera.yaml")
        calibrate = _join("rotavat", "calibrate", seq, *extra, "--out", camera_file)
        then = f"then {align} --camera {shlex.quote(str(camera_file))}"
    else:
        calibrate, then = _join("rotavat", "calibrate", seq, *extra), f"then {align}"
    return Remedies(calibrate, then, f"{align} --camera FILE (a camera.yaml you wrote: {CAMERA_DOC})",
                    f"{align} {ACCEPT_FLAG}")


def render_remedies(seq: str | Path, own: bool, aligned: bool = False, reader_flags: tuple[str, ...] = (),
                    command: str = "render") -> Remedies:
    """``rotavat render``'s (or another ``command`` drawing rows in their cameras: ``view``) for one row: ``own`` =
    the row's own camera.yaml (else ``--camera``); ``aligned`` = the row is align's output (its camera is the one it
    was aligned into: align its input again); ``reader_flags``: the row is an HPS tool's output read with ``--from``
    (its calibration goes to a file given with --camera)."""
    accept = f"add {ACCEPT_FLAG} to the {command} command"
    if reader_flags:
        if own:  # the camera its format carried: nothing given on the command line replaces it
            return Remedies("", "", "", accept)
        camera_file = imported_output(seq, "_camera.yaml")
        return Remedies(_join("rotavat", "calibrate", seq, *reader_flags, "--out", camera_file),
                        f"then {command} with --camera {shlex.quote(str(camera_file))}",
                        f"{command} --camera FILE (a camera.yaml you wrote: {CAMERA_DOC})", accept)
    if aligned:
        return Remedies("rotavat calibrate INPUT", f"then rotavat align INPUT --out {shlex.quote(str(seq))}, INPUT being "
                        f"the sequence {shlex.quote(str(seq))} was aligned from", "", accept)
    calibrate = _join("rotavat", "calibrate", seq)
    camera_yaml = Path(seq) / "camera.yaml"
    if own:
        return Remedies(calibrate, f"it rewrites {shlex.quote(str(camera_yaml))}; then {command} again",
                        f"replace {shlex.quote(str(camera_yaml))} by a camera.yaml you wrote ({CAMERA_DOC})", accept)
    return Remedies(calibrate, f"then {command} again: a row's own {camera_yaml.name} is used before --camera",
                    f"{command} --camera FILE (a camera.yaml you wrote: {CAMERA_DOC})", accept)


def batch_remedies(root: str | Path, out: str | Path) -> Remedies:
    """``rotavat batch``'s: rerun it with what you know of the camera, with --camera FILE, or accepting it."""
    batch = _join("rotavat", "batch", root, "--out", out)
    return Remedies(f"rerun {batch} (your other options as before) adding", "every sequence is calibrated with them",
                    f"--camera FILE instead (a camera.yaml you wrote: {CAMERA_DOC}; every sequence is aligned into it)",
                    f"{ACCEPT_FLAG} instead")


def flags_not_given(fit: Mapping | None) -> tuple[str, ...]:
    """The flags of what a user may know of a camera (focal, height, pitch) that the fit did not already take
    as given (``fit.fixed``); all of them for a camera without a fit block.

    >>> flags_not_given({"fixed": {"focal_px": "given", "pitch_deg": "given"}})
    ('--camera-height M',)
    """
    fixed = fit.get("fixed", {}) if isinstance(fit, Mapping) else {}
    fixed = fixed if isinstance(fixed, Mapping) else {}
    return tuple(flag for key, flag in _KNOWN if fixed.get(key) not in ("given", "declared"))


def what_to_give(fit: Mapping | None, command: str = "") -> str:
    """The advice for an implausible camera that never repeats what the user gave: the flags not yet given (after
    ``command``, when one is named), else :data:`OTHER_CAUSES`.

    >>> what_to_give({"fixed": {"focal_px": "given"}}, "rotavat calibrate seq")
    'give what you know: rotavat calibrate seq --camera-height M [--pitch DEG]'
    >>> what_to_give({"fixed": {"focal_px": "given", "height_m": "given", "pitch_deg": "given"}}).startswith("the people")
    True
    """
    flags = flags_not_given(fit)
    if not flags:
        return OTHER_CAUSES
    return f"give what you know: {' '.join([command, *flags]).strip()}" if command else \
        f"give what you know ({', '.join(flags)})"


def check_fit(what: str, fit: Mapping | None, accept: bool, remedies: Remedies) -> str | None:
    """The gate: None for a plausible camera; the warning to show for an implausible one used anyway
    (``accept``, or recorded as accepted); else :class:`ImplausibleCameraError` on one line.

    ``what`` names the camera: its file, or "the camera calibrated from SEQ".
    """
    findings = implausible_findings(fit)
    if not findings:
        return None
    found = f"{what}: implausible camera ({'; '.join(findings)})"
    if accept:
        return f"{found}, used anyway ({ACCEPT_FLAG})"
    if is_accepted(fit):
        return f"{found}, used as accepted earlier with {ACCEPT_FLAG} (fit: accepted: true)"
    flags = flags_not_given(fit)
    fixes = [f"{remedies.calibrate} {' '.join(flags)} ({remedies.then})" if remedies.calibrate and flags else "",
             remedies.camera, f"{remedies.accept} to use it anyway"]
    given = [f for f in fixes[:-1] if f]
    advice = f"give what you know: {', or '.join([*given, fixes[-1]])}" if given else fixes[-1]
    if not flags:  # everything one may know of the camera was given: what else is wrong comes first
        advice = f"{OTHER_CAUSES}; or {advice}"
    raise ImplausibleCameraError(" ".join(f"{found}; {advice}".split()))


def camera_what(chosen: AlignCamera, seq_label: str) -> str:
    """How the gate names an align camera: its file, or the camera calibrated from the sequence (and its file)."""
    if chosen.origin == CALIBRATED:
        written = f" ({chosen.source})" if chosen.source.endswith(".yaml") else ""
        return f"the camera calibrated from {seq_label}{written}"
    return chosen.source or "the camera"


def check_align_camera(chosen: AlignCamera, seq_label: str, accept: bool,
                       remedies: Remedies) -> tuple[AlignCamera, str | None]:
    """The camera to align into once past the gate (its fit records ``accepted: true`` when ``accept`` let an
    implausible one through) and the warning to show (None for a plausible camera)."""
    warning = check_fit(camera_what(chosen, seq_label), chosen.fit, accept, remedies)
    if warning is not None and accept:
        chosen = AlignCamera(chosen.camera, accepted_fit(chosen.fit), chosen.origin, chosen.source)
    return chosen, warning
