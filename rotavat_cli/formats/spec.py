"""SPEC demo output: per-image ``spec_results/<image>.pkl`` plus CamCalib's ``camcalib/<image>.pkl``.

Source: mkocabas/SPEC ``scripts/spec_demo.py``, ``spec/tester.py`` (``run_on_image_folder``:
``joblib.dump(output, spec_results/<stem>.pkl)``), ``spec/utils/cam_params.py``
(``read_cam_params``), ``scripts/camcalib_demo.py`` (``f_pix = H / 2 / tan(vfov / 2)``, angles
in radians), ``camcalib/vis_utils.py`` (horizon: positive pitch = looking down), PARE's
``SMPLCamHead`` (``perspective_projection``: ``K (R X + t)``) and ``batch_euler2matrix``.

- ``spec_results/<stem>.pkl`` (joblib): ``smpl_vertices`` (P, 6890, 3) and ``smpl_joints3d``
  (P, 49, 3; SPIN order) in SPEC's gravity-aligned frame (y = gravity down when the camera is
  level) *without* translation; ``pred_cam_t`` (P, 3); ``smpl_joints2d`` (P, 49, 2) in
  original-image pixels; ``pred_pose`` (P, 24, 3, 3), ``pred_shape`` (P, 10).
- ``camcalib/<image file name>.pkl``: ``pitch``, ``roll``, ``vfov`` (radians), ``f_pix`` (px).
- Frame: camera frame = ``R @ X + pred_cam_t`` with ``R = Rx(pitch) Rz(roll)``
  (``batch_euler2matrix([pitch, 0, roll])``): OpenCV axes, metres. Principal point = image centre.
- ``camera.yaml``: focal, pitch and roll are the medians of CamCalib's per-image estimates; the
  camera height (not estimated by SPEC) is the median, over all people, of the height of the
  camera above the plane through each mesh's mid-sole point, perpendicular to CamCalib's gravity.
- Image size: ``--image-size``, else the principal point recovered from ``smpl_joints2d``
  against the projected 3D joints (SPEC uses the exact image centre).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..geometry.camera import Camera, pitch_roll_from_up
from ..errors import file_error
from ..geometry.focal import ASSUMED
from ..bodies.landmarks import foot_head_points
from ..geometry.rotations import axis_angle_to_matrix
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names, natural_key
from .frames import people_frame
from .imported import Conclusion, FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces
from .smpl import lbs

_UP_SPEC_WORLD = np.array([0.0, -1.0, 0.0])  # SPEC's world: y = gravity (down), as SMPL in the camera when level


def sniff(path: Path) -> str | None:
    """'spec' for a SPEC output folder (spec_results/ and camcalib/)."""
    if path.is_dir() and (path / "spec_results").is_dir() and (path / "camcalib").is_dir():
        return "spec"
    return None


def spec_rotation(pitch_rad: float, roll_rad: float) -> np.ndarray:
    """SPEC's camera rotation ``batch_euler2matrix([pitch, 0, roll])`` = Rx(pitch) @ Rz(roll) (3, 3)."""
    rx = axis_angle_to_matrix(np.array([1.0, 0.0, 0.0]), pitch_rad)
    rz = axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), roll_rad)
    return rx @ rz


def _folders(src: Path) -> tuple[Path, Path]:
    """(spec_results, camcalib) folders of a SPEC output directory."""
    if src.name == "spec_results" and (src.parent / "camcalib").is_dir():
        return src, src.parent / "camcalib"
    if not sniff(src):
        raise file_error(src, "not a SPEC output folder (expected spec_results/ and camcalib/ inside)")
    return src / "spec_results", src / "camcalib"


def _stem_of_camcalib(path: Path) -> str:
    """'img001.jpg.pkl' -> 'img001'."""
    return Path(path.stem).stem


def _scalar(obj: object, name: str, source: object) -> float:
    arr = as_array(np.asarray(obj) if not isinstance(obj, np.ndarray) else obj, name, source)
    if arr.size != 1 or not np.isfinite(arr).all():
        raise file_error(source, f"'{name}' must be one finite number")
    return float(arr.reshape(()))


def _camcalib(path: Path) -> dict[str, float]:
    data = load_file(path)
    cam = {key: _scalar(get(data, key, path), key, path) for key in ("pitch", "roll", "vfov", "f_pix")}
    if cam["f_pix"] <= 0 or not 0 < cam["vfov"] < np.pi:
        raise file_error(path, f"'f_pix' must be a positive focal length and 'vfov' a field of view in (0, pi), got "
                               f"{cam['f_pix']:g} and {cam['vfov']:g}")
    return cam


def _infer_image_size(j3d_cam: np.ndarray, j2d: np.ndarray, focal: float) -> tuple[int, int] | None:
    """(W, H) = 2 x principal point recovered from u - f x / z (SPEC uses cx, cy = W / 2, H / 2)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = j2d[..., :2] - focal * j3d_cam[..., :2] / j3d_cam[..., 2:3]
    offset = offset.reshape(-1, 2)
    offset = offset[np.isfinite(offset).all(axis=1)]
    if len(offset) == 0 or np.ptp(offset, axis=0).max() > 1.0:
        return None
    cx, cy = np.median(offset, axis=0)
    return (int(round(2 * cx)), int(round(2 * cy)))


def read_spec(src: Path, opts: ImportOptions) -> ImportedSequence:
    """SPEC demo output folder -> contract frames + camera.yaml."""
    results_dir, camcalib_dir = _folders(src)
    calib = {_stem_of_camcalib(p): p for p in camcalib_dir.glob("*.pkl")}
    results = {p.stem: p for p in results_dir.glob("*.pkl")}
    stems = sorted(set(calib) | set(results), key=natural_key)
    if not stems:
        raise file_error(src, "no SPEC results (spec_results/*.pkl) or CamCalib files (camcalib/*.pkl)")
    missing = [s for s in results if s not in calib]
    if missing:
        raise file_error(camcalib_dir, f"no CamCalib parameters for image '{missing[0]}'")
    cams = {stem: _camcalib(calib[stem]) for stem in stems}
    model = opts.body_model
    check_model_kind(model, src, "SPEC", "smpl")
    warnings: list[str] = []

    def load(stem: str) -> dict[str, np.ndarray] | None:
        if stem not in results:
            return None
        path = results[stem]
        data = load_file(path)
        cam = cams[stem]
        R = spec_rotation(cam["pitch"], cam["roll"])
        t = as_array(get(data, "pred_cam_t", path), "pred_cam_t", path, ndim=2, last=(3,))
        verts = as_array(get(data, "smpl_vertices", path), "smpl_vertices", path, ndim=3, last=(3,))
        j3d = as_array(get(data, "smpl_joints3d", path), "smpl_joints3d", path, ndim=3, last=(3,))
        out = {"vertices": verts @ R.T + t[:, None], "j3d": j3d @ R.T + t[:, None]}
        if data.get("smpl_joints2d") is not None:
            out["keypoints_2d"] = as_array(data["smpl_joints2d"], "smpl_joints2d", path, ndim=3, last=(2,))
        if model is not None:
            pose = as_array(get(data, "pred_pose", path), "pred_pose", path)
            betas = as_array(get(data, "pred_shape", path), "pred_shape", path, ndim=2)
            _, joints = lbs(model, betas, pose)
            out["joints"] = joints @ R.T + t[:, None]
        else:
            out["joints"] = out["j3d"]
        return out

    # Image size: the user's, else recovered from the first frame with people.
    if opts.image_size is not None:
        image_size, size_origin = opts.image_size, "--image-size"
    else:
        image_size = None
        for stem in stems:
            people = load(stem)
            if people is not None and len(people["vertices"]) and "keypoints_2d" in people:
                image_size = _infer_image_size(people["j3d"], people["keypoints_2d"], cams[stem]["f_pix"])
                if image_size:
                    break
        if image_size is None:
            raise file_error(src, "the image size is not stored in SPEC results and could not be recovered from "
                                  "smpl_joints2d; pass --image-size W H")
        size_origin = "recovered from smpl_joints2d (principal point = image centre)"
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)
    for stem in stems:  # CamCalib's focal is tied to the image height: check it
        cam = cams[stem]
        implied_h = 2.0 * cam["f_pix"] * np.tan(cam["vfov"] / 2.0)
        if abs(implied_h - image_size[1]) > 2.0:
            warnings.append(f"{calib[stem]}: CamCalib's f_pix and vfov imply an image height of {implied_h:.0f} px, "
                            f"not {image_size[1]}")
            break
    focals = np.array([cams[s]["f_pix"] for s in stems])
    ups = np.stack([spec_rotation(cams[s]["pitch"], cams[s]["roll"]) @ _UP_SPEC_WORLD for s in stems])
    names = frame_names(stems, warnings)
    vertex_counts: dict[str, int] = {}  # V of each results file seen: an empty image after one has (0, V, 3) vertices

    def n_verts_before(index: int) -> int | None:
        """V of the results file of the last image before ``index`` that has one (None: no such image)."""
        stem = next((s for s in reversed(stems[:index]) if s in results), None)
        if stem is None:
            return None
        if stem not in vertex_counts:
            path = results[stem]
            verts = as_array(get(load_file(path), "smpl_vertices", path), "smpl_vertices", path, ndim=3,
                             last=(3,))
            vertex_counts[stem] = verts.shape[1]
        return vertex_counts[stem]

    def build(index: int, notes: FrameNotes) -> Frame:
        stem = stems[index]
        people = load(stem)
        source = results.get(stem, calib[stem])
        extra = {"focal_length": np.float64(cams[stem]["f_pix"])}
        if people is None:
            return people_frame(names[index], source, notes.warnings, n_verts=n_verts_before(index), extra=extra)
        verts = people["vertices"]
        n_verts = vertex_counts[stem] = verts.shape[1]
        feet_cam, _ = foot_head_points(verts)
        notes.facts["ground_m"] = (-(feet_cam @ ups[index]))[np.isfinite(feet_cam).all(axis=1)].tolist()
        return people_frame(names[index], source, notes.warnings, vertices=verts, joints=people["joints"],
                            keypoints_2d=people.get("keypoints_2d"), faces=model_faces(model, n_verts),
                            n_verts=n_verts, extra=extra, keypoints_layout="spin49")

    def conclude(notes: list[FrameNotes]) -> Conclusion:
        ground = [h for n in notes for h in n.facts.get("ground_m", ())]
        found: list[str] = []
        camera, fit = _camera(image_size, principal_point, focals, ups, ground, found, src)
        return Conclusion(warnings=found, camera=camera, camera_fit=fit)

    meta = base_meta("spec", src, opts, image_size, float(np.median(focals)), principal_point, focal_kind=ASSUMED)
    meta["import"].update({
        "source_frames": stems,
        "image_size_from": size_origin,
        "joints_layout": "smpl24" if model is not None else "spin49 (OpenPose-25 + 24 SPIN joints)",
        "root_joint": 0 if model is not None else 8,
        "keypoints_2d_layout": "spin49",
        "feet_heads_from": feet_heads_from("spin49", True),
        "conventions": "camera frame = OpenCV, metres: X_cam = Rx(pitch) Rz(roll) X + pred_cam_t; per-frame focal = "
                       "CamCalib f_pix; principal point = image centre",
    })
    return ImportedSequence(tuple(names), build, meta, warnings, conclude=conclude, camera_from_frames=True)


def _camera(image_size: tuple[int, int], principal_point: tuple[float, float], focals: np.ndarray, ups: np.ndarray,
            ground: list[float], warnings: list[str], src: Path) -> tuple[Camera | None, dict | None]:
    """camera.yaml from CamCalib (focal, pitch, roll medians) and the people (height)."""
    heights = np.asarray(ground)
    heights = heights[heights > 0]
    if len(heights) == 0:
        warnings.append(f"{src}: no people above a ground plane: camera height unknown, camera.yaml not written")
        return None, None
    pitch, roll = pitch_roll_from_up(ups)
    camera = Camera(image_size, float(np.median(focals)), principal_point, float(np.median(pitch)),
                    float(np.median(roll)), float(np.median(heights)))
    fit = {
        "method": "spec-camcalib",
        "height_from": "median camera height above the plane through each SPEC mesh's mid-sole, "
                       "perpendicular to CamCalib's gravity",
        "people": int(len(heights)),
        "frames": int(len(focals)),
        "std": {"focal_px": float(np.std(focals)), "pitch_deg": float(np.degrees(np.std(pitch))),
                "roll_deg": float(np.degrees(np.std(roll))), "height_m": float(np.std(heights))},
    }
    return camera, fit


READERS = {"spec": read_spec}
