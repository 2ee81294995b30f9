"""GLAMR results: the ``grecon/<seq>_seed<seed>.pkl`` pickle of ``global_recon/run_demo.py``.

Source (NVlabs/GLAMR; file @ the commit read, function):

- ``global_recon/run_demo.py`` @0137814: ``out_dict = grecon_model.optimize(in_dict)``, then
  ``pickle.dump(out_dict, open(f'{out_dir}/grecon/{seq_name}_seed{seed}.pkl', 'wb'))`` (plain pickle).
- ``global_recon/models/global_recon_model.py`` @17cfe74 ``GlobalReconOptimizer.init_data``,
  ``forward``, ``optimize`` (``tensor_to_numpy``: every tensor becomes a numpy array,
  ``lib/utils/torch_utils.py`` @8c2213f): a dict with ``person_data`` ``{person index: {...}}``,
  ``cam_pose`` (T, 4, 4) world -> camera (``init_data``: ``root_trans_world =
  transform_trans(cam_pose_inv, root_trans_cam)``; ``forward``: ``joint_3d_cam =
  transform_trans(cam_pose, joint_3d)`` projected with ``cam_K``), ``cam_pose_inv``, ``meta``
  (``num_fr``), ``seq_len``, ``gt`` ... Per person, over all T frames: ``smpl_orient_world`` (T, 3)
  and ``smpl_pose`` (T, 69) axis-angle, ``smpl_beta`` (T, 10), ``root_trans_world`` (T, 3),
  ``scale`` (None, or (T,) about the root), ``cam_K`` (T, 3, 3) (zero where not detected),
  ``visible_orig`` (T,) the detections, ``visible`` / ``vis_frames`` after GLAMR's pose filter,
  ``exist_frames`` (first to last detection; between them occluded frames are filled by its
  motion infiller), ``kp_2d_pred`` (T, 26, 2) its body26fk joints projected with ``cam_K``.
- ``lib/models/smpl.py`` @8c2213f ``SMPL.forward(root_trans=...)``: the body is translated so its
  joint 0 lands on ``root_trans`` (scaled about it by ``root_scale``); ``global_recon/vis/vis_grecon.py``
  @c15c8fc ``load_scene`` poses with ``orig_joints=True``: joint 0 is SMPL's pelvis, and the
  camera view (``update_camera``, ``cam_in_world``) sits at ``cam_pose_inv`` with x right, y down,
  z forward (OpenCV). GLAMR's optimisation and ``global_recon/utils/evaluator.py`` @eaf2044 pose
  with ``orig_joints=False``, where joint 0 is SPIN's regressed "Pelvis (MPII)"
  (``J_regressor_extra.npy``, not part of the SMPL model): there the body sits a few centimetres
  away. The importer follows the visualiser (what GLAMR shows, computable from the SMPL model alone).
- ``pose_est/hybrik_demo/demo.py`` @19def25: HybrIK's translation is rescaled to a focal of 1000 px
  on the full image with the principal point at its centre, and that is ``cam_K`` (focal 1000,
  ``(W/2, H/2)``); frames are the video's images in order (``run_pose_est_on_video``).

Conversion:

- Frame ``t`` (named by its index: GLAMR extracts the video's frames as ``%06d.jpg``): every person
  detected there (``visible_orig``, else ``visible``; occluded, infilled frames are left out).
- Meshes: SMPL(``smpl_orient_world``, ``smpl_pose``, ``smpl_beta``) moved so its pelvis joint is at
  ``root_trans_world`` (scaled about it when ``scale`` is set; a scale that is not positive where the
  person is detected is refused), then ``cam_pose[t]``
  (``R X + t``): OpenCV camera frame, metres. Needs ``--smpl-model`` (SMPL_NEUTRAL.npz; GLAMR uses
  the neutral SMPL); without it: joints = the root (pelvis) only, and the 2D keypoints.
- ``keypoints_2d``: ``kp_2d_pred``, layout body26fk (GLAMR ``get_ordered_joint_names``: pelvis
  (MPII), hips, spine, knees, neck, ankles, OpenPose toes and heels, nose, eyes, ears, shoulders,
  elbows, wrists), original-image pixels, projected from GLAMR's own (MPII-pelvis) placement.
- Focal: ``cam_K``; ``focal_rule: glamr`` (1000 px) when it is that, else ``assumed`` without a
  rule (a dataset's intrinsics given to GLAMR) and a warning. Image size ``2 (cx, cy)`` unless
  ``--image-size``.
- ``person_ids``: the ``person_data`` keys (GLAMR's tracker ids).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.camera import world_to_cam
from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .ids import int64_ids
from .image_size import centre_image_size
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces, no_model_warning
from .smpl import BodyModel, lbs, pose_from_body

__all__ = ["KEYPOINTS_LAYOUT", "READERS", "read_glamr", "sniff"]

KEYPOINTS_LAYOUT = "body26fk (GLAMR lib/models/smpl.py get_ordered_joint_names)"
_GLOB = "*_seed*.pkl"
_MAX_SNIFF_BYTES = 512 << 20  # pickles beyond this are not opened just to guess a format
_FOCAL_RTOL = 1e-4  # float32 storage of cam_K


def _candidates(folder: Path) -> list[Path]:
    """GLAMR result pickles in ``folder`` or its ``grecon/`` subfolder."""
    found = sorted(folder.glob(_GLOB))
    if (folder / "grecon").is_dir():
        found += sorted((folder / "grecon").glob(_GLOB))
    return found


def _is_glamr(data: object) -> bool:
    return isinstance(data, Mapping) and isinstance(data.get("person_data"), Mapping) and "cam_pose" in data


def sniff(path: Path) -> str | None:
    """'glamr' for GLAMR's result pickle, or a folder holding exactly one (itself or in grecon/)."""
    if path.is_dir():
        found = _candidates(path)
        if len(found) != 1:
            return None
        path = found[0]
    if not (path.is_file() and path.suffix == ".pkl") or path.stat().st_size > _MAX_SNIFF_BYTES:
        return None
    return "glamr" if _is_glamr(load_file(path)) else None


def _result_file(src: Path) -> Path:
    """``src`` itself, or the one result pickle of folder ``src``."""
    if src.is_file():
        return src
    found = _candidates(src)
    if len(found) != 1:
        raise file_error(src, f"expected one GLAMR result '{_GLOB}' in the folder or its grecon/, found {len(found)}"
                              + (" (one per seed: pass the file)" if found else ""))
    return found[0]


@dataclass(frozen=True)
class _Person:
    """One GLAMR person over all T frames (world frame, metres)."""

    pid: int
    orient_world: np.ndarray  # (T, 3) axis-angle
    body_pose: np.ndarray  # (T, 69) axis-angle, SMPL joints 1..23
    betas: np.ndarray  # (T, B)
    root_world: np.ndarray  # (T, 3) pelvis
    scale: np.ndarray | None  # (T,) about the root, or None
    present: np.ndarray  # (T,) bool: detected in that frame
    cam_K: np.ndarray  # (T, 3, 3)
    keypoints_px: np.ndarray | None  # (T, 26, 2) kp_2d_pred


def _person(key: object, entry: object, n_frames: int, source: str) -> _Person:
    """Validate one ``person_data`` entry."""
    try:
        pid = int(key)  # type: ignore[call-overload]
    except (TypeError, ValueError, OverflowError):
        raise file_error(source, f"person key {str(key)[:40]!r} is not an integer id") from None
    int64_ids([pid], "person id", source)
    where = f"{source} [person {pid}]"

    def series(name: str, trailing: tuple[int, ...], kinds: str = "fiu") -> np.ndarray:
        arr = as_array(get(entry, name, where), name, where, kinds=kinds)
        if arr.shape != (n_frames, *trailing):
            raise file_error(where, f"'{name}' must be {[n_frames, *trailing]} (T = {n_frames} frames of cam_pose), "
                                    f"got {list(arr.shape)}")
        return arr

    visible = get(entry, "visible_orig", where, required=False)
    present = series("visible_orig" if visible is not None else "visible", (), "fiub") > 0
    if get(entry, "exist_frames", where, required=False) is not None:
        present &= series("exist_frames", (), "fiub").astype(bool)
    betas = as_array(get(entry, "smpl_beta", where), "smpl_beta", where, ndim=2)
    if len(betas) != n_frames:
        raise file_error(where, f"'smpl_beta' must be (T, B) with T = {n_frames}, got {list(betas.shape)}")
    scale = get(entry, "scale", where, required=False)
    kp = get(entry, "kp_2d_pred", where, required=False)
    return _Person(pid, series("smpl_orient_world", (3,)), series("smpl_pose", (69,)), betas,
                   series("root_trans_world", (3,)), None if scale is None else series("scale", ()), present,
                   series("cam_K", (3, 3)), None if kp is None else series("kp_2d_pred", (26, 2)))


def _intrinsics(people: list[_Person], source: Path, warnings: list[str]) -> np.ndarray:
    """cam_K (3, 3) of the first detection; a warning when others differ."""
    detected = [p.cam_K[p.present] for p in people if p.present.any()]
    if not detected:
        raise file_error(source, "no person is detected in any frame (no cam_K to read the focal from)")
    K = detected[0][0]
    if not all(np.allclose(k, K, rtol=_FOCAL_RTOL) for k in detected):
        warnings.append(f"{source}: cam_K differs between frames or people; using the first detection's")
    if not (np.all(np.isfinite(K)) and K[0, 0] > 0 and K[1, 1] > 0 and K[0, 2] > 0 and K[1, 2] > 0):
        raise file_error(source, f"cam_K must have positive focal and principal point, got {K[:2].tolist()}")
    return K


def _focal_rule(K: np.ndarray, image_size: tuple[int, int], source: Path, warnings: list[str]) -> str | None:
    """'glamr' when cam_K is GLAMR's own (1000 px, centred), else None with a warning."""
    rule_focal = focal_from_rule("glamr", image_size)
    focal = 0.5 * (K[0, 0] + K[1, 1])
    centred = np.allclose(2 * K[:2, 2], image_size, atol=1.0)
    if centred and np.allclose([K[0, 0], K[1, 1]], rule_focal, rtol=_FOCAL_RTOL):
        return "glamr"
    warnings.append(f"{source}: cam_K focal {focal:.1f} px is not GLAMR's {rule_focal:.0f} px: intrinsics given to "
                    "GLAMR; declared assumed; pass calibrate --focal if it is your camera's calibration")
    return None


def _check_root_scale(person: _Person, source: Path) -> None:
    """A root scale must be positive where the person is detected: 0 collapses the mesh onto its root,
    a negative one turns it inside out (InputError naming the person, the key and the first frame)."""
    if person.scale is None:
        return
    bad = np.flatnonzero(person.present & ~(np.isfinite(person.scale) & (person.scale > 0)))
    if len(bad):
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise file_error(f"{source} [person {person.pid}]",
                         f"'scale' is {person.scale[bad[0]]:g} in frame {bad[0]}{more}: GLAMR's root scale must be "
                         "positive (the mesh would collapse onto its root)")


def _check_model(model: BodyModel | None, source: Path, warnings: list[str]) -> BodyModel | None:
    if model is None:
        warnings.append(no_model_warning("GLAMR") + " (joints = the pelvis only)")
    return check_model_kind(model, source, "GLAMR", "smpl")


def _posed_world(model: BodyModel, people: list[_Person], t: int) -> tuple[np.ndarray, np.ndarray]:
    """World vertices (P, V, 3) and joints (P, 24, 3) of ``people`` in frame ``t``: SMPL posed, its pelvis
    moved to ``root_trans_world`` (vis_grecon ``orig_joints=True``), scaled about it by ``scale``."""
    betas = np.stack([p.betas[t] for p in people])
    pose = pose_from_body(np.stack([p.orient_world[t] for p in people]), np.stack([p.body_pose[t] for p in people]),
                          model.n_joints)
    verts, joints = lbs(model, betas, pose)
    pelvis = joints[:, :1]
    root = np.stack([p.root_world[t] for p in people])[:, None]
    scale = np.array([1.0 if p.scale is None else p.scale[t] for p in people])[:, None, None]
    return (verts - pelvis) * scale + root, (joints - pelvis) * scale + root


def read_glamr(src: Path, opts: ImportOptions) -> ImportedSequence:
    """GLAMR result pickle (or its folder) -> contract frames in each video frame's camera."""
    path = _result_file(src)
    data = load_file(path)
    if not _is_glamr(data):
        raise file_error(path, "not a GLAMR result (expected a dict with 'person_data' and 'cam_pose')")
    cam_pose = as_array(data["cam_pose"], "cam_pose", path, ndim=3, last=(4, 4))
    n_frames = len(cam_pose)
    people = [_person(key, entry, n_frames, str(path)) for key, entry in data["person_data"].items()]
    if len({p.pid for p in people}) != len(people):
        raise file_error(path, "person ids repeat in 'person_data'")
    warnings: list[str] = []
    model = _check_model(opts.body_model, path, warnings)
    if model is not None:  # without a model only the roots are imported: the scale is not used
        for person in people:
            _check_root_scale(person, path)
    K = _intrinsics(people, path, warnings)
    image_size = opts.image_size or centre_image_size(K[0, 2], K[1, 2], path, "cam_K's principal point")
    rule = _focal_rule(K, image_size, path, warnings)
    with_keypoints = bool(people) and all(p.keypoints_px is not None for p in people)
    faces = model_faces(model, None if model is None else model.n_verts)
    names = frame_names([f"{t:06d}" for t in range(n_frames)], warnings)

    def build(index: int, notes: FrameNotes) -> Frame:
        here = [p for p in people if p.present[index]]
        R_cam_from_world, t_cam_from_world = cam_pose[index, :3, :3], cam_pose[index, :3, 3]
        verts = None
        if model is not None and here:
            verts_world, joints_world = _posed_world(model, here, index)
            verts = world_to_cam(verts_world, R_cam_from_world, t_cam_from_world)
            joints = world_to_cam(joints_world[:, :24], R_cam_from_world, t_cam_from_world)
        elif model is not None:
            joints = np.zeros((0, 24, 3))
        else:
            roots_world = np.array([p.root_world[index] for p in here]).reshape(-1, 1, 3)
            joints = world_to_cam(roots_world, R_cam_from_world, t_cam_from_world)
        keypoints = np.array([p.keypoints_px[index] for p in here]).reshape(-1, 26, 2) if with_keypoints else None
        return people_frame(names[index], f"{path} [frame {index}]", notes.warnings, vertices=verts, joints=joints,
                            keypoints_2d=keypoints, person_ids=np.array([p.pid for p in here], dtype=np.int64),
                            faces=faces, n_verts=None if model is None else model.n_verts,
                            keypoints_layout=KEYPOINTS_LAYOUT if with_keypoints else None)

    focal = 0.5 * (K[0, 0] + K[1, 1])
    meta = base_meta("glamr", path, opts, image_size, focal, (float(K[0, 2]), float(K[1, 2])), focal_kind=ASSUMED,
                     focal_rule=rule)
    meta["import"].update({
        "source_frames": names,
        "image_size_from": "--image-size" if opts.image_size else "2 x cam_K principal point (HybrIK's W/2, H/2)",
        "joints_layout": "smpl24" if model is not None else "pelvis (SMPL joint 0, root_trans_world)",
        "root_joint": 0,
        "keypoints_2d_layout": KEYPOINTS_LAYOUT if with_keypoints else None,
        "feet_heads_from": feet_heads_from(KEYPOINTS_LAYOUT if with_keypoints else None, model is not None),
        "person_ids": "GLAMR person_data keys (tracker ids); people per frame = detections (visible_orig)",
        "conventions": "camera frame = OpenCV, metres; vertices = cam_pose[t] (SMPL(smpl_orient_world, smpl_pose, "
                       "smpl_beta) - pelvis + root_trans_world), as GLAMR's visualiser (its optimiser places "
                       "SPIN's MPII pelvis there instead); focal = cam_K (GLAMR's HybrIK: 1000 px); frames named by "
                       "video frame index",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"glamr": read_glamr}
