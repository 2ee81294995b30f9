"""The person model of calibration: a head pixel predicted in closed form from its foot pixel.

A person stands upright on the ground (conventions: docs/conventions.md). For a camera (focal
``f``, pitch, roll, height ``h``; up vector ``n`` in the camera frame) back-project the foot pixel
onto the ground, put the head ``S`` metres above it along ``n`` and project it. With ``F`` the foot
pixel relative to the principal point:

- ``d = -n . (F/f, 1)``: the foot ray against up (``d > 0``: the ray meets the ground in front);
- ``M = d (f n_xy - n_z F)``: the direction the head moves from the foot, in pixels;
- ``k = S / h`` and ``z = 1 + k n_z d``: the head's depth over the foot's (``z > 0``: in front);
- the predicted head is ``F + (k / z) M``.

``d`` and ``M`` depend on the focal and the pitch/roll only (:func:`foot_terms`), which is what
makes the paper grid fast (:mod:`.grid`: the same model with ``k / z = 1 / (h/S - g)``,
``g = -n_z d``). Optional parts: a division-model lens distortion undistorts the foot first and
distorts the predicted head back into the image, where it is compared with the observed head (the
error is in image pixels, where the clicks' noise is: compared after undistorting both, a lens that
shrinks the image's periphery would also shrink the errors there, and the fit leaned toward it:
+0.02, half a std, from one walker's clicks of a pinhole camera), and box-derived points put the
head ``b`` metres beyond the foot (``k = (S rho + b) / (h rho + b)``).

:func:`head_errors` is the one implementation: the paper grid's exact re-scoring, the
refinement and the uncertainty all call it, over ``Q`` parameter sets at once.

>>> from rotavat_cli.geometry.camera import Camera
>>> cam = Camera((640, 480), 500.0, None, 0.5, 0.02, 4.0)
>>> feet = np.array([[100.0, 300.0], [500.0, 420.0]])
>>> heads = predict_heads_px(feet, 500.0, 0.5, 0.02, 4.0, (320.0, 240.0), 1.7)
>>> bool(np.allclose(heads, cam.project(cam.backproject_px_to_ground(feet) + 1.7 * cam.up_cam)))
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import up_vector_cam
from ..geometry.lens import distort_scale, undistort_rel_px
from .params import BOX_DEPTH, DISTORTION, FOCAL, HEIGHT, N_PARAMS, PITCH, ROLL, slot

__all__ = ["RAY_EPS", "Z_MIN", "CameraTerms", "camera_terms", "foot_ray_d", "foot_terms", "undistort", "head_errors", "head_gain", "predict_heads_px"]

RAY_EPS = 1e-12  # foot ray "parallel to the ground" (as camera.backproject_px_to_plane)
Z_MIN = 0.05  # refinement: head depth / foot depth below this -> head (nearly) behind the camera, invalid pair
_Z_FLOOR = 1e-12  # z is clamped here when an invalid pair's error is still computed (no division by zero)


def foot_terms(u: np.ndarray, v: np.ndarray, f: np.ndarray, nx, ny, nz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``d``, ``M_u``, ``M_v`` of the model (module docstring), broadcast.

    u, v: foot pixels relative to the principal point; f: focal px; nx, ny, nz: world up in the
    camera frame. Shapes broadcast: ``(N,)`` pairs against ``(Q, 1)`` parameter sets (refinement)
    or ``(1, B)`` against ``(F, 1)`` focals and scalar ``n`` (the grid's kernel).
    """
    d = foot_ray_d(u, v, f, nx, ny, nz)
    return d, d * (f * nx - nz * u), d * (f * ny - nz * v)


def foot_ray_d(u: np.ndarray, v: np.ndarray, f: np.ndarray, nx, ny, nz) -> np.ndarray:
    """The model's ``d = -n . (F/f, 1)`` alone (:func:`foot_terms`'s first term, same arguments and broadcasting):
    ``d > 0`` when the foot ray meets the ground in front of the camera."""
    return -(nx * u + ny * v) / f - nz


def undistort(rel_feet: np.ndarray, diff: np.ndarray, lam: np.ndarray, radius_px: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """Division-model undistortion (:func:`rotavat_cli.geometry.lens.undistort_rel_px`) of feet and heads -> (Q, N, 2) each.

    rel_feet, diff: (N, 2) px about the principal point; lam: (Q, 1); radius_px: R, the half-diagonal.
    Returns the undistorted feet and ``feet - heads``, both undistorted.
    """
    feet = undistort_rel_px(rel_feet, lam, radius_px)
    return feet, feet - undistort_rel_px(rel_feet - diff, lam, radius_px)


@dataclass(frozen=True)
class CameraTerms:
    """What the model needs of parameter sets ``params (Q, 6)`` and pairs, whatever the stature: the pairs
    (with a lens: the feet undistorted, the observed heads kept in the image as ``image_heads``), the focal, height and box depth (Q, 1), the up vector's
    components (Q, 1) and ``d``, ``M_u``, ``M_v`` (Q, N) (:func:`foot_terms`). A refinement step evaluates the
    model at several statures for one set of parameters: these are computed once."""

    rel_feet: np.ndarray
    diff: np.ndarray
    f: np.ndarray
    h: np.ndarray
    box: np.ndarray
    n: tuple[np.ndarray, np.ndarray, np.ndarray]
    d: np.ndarray
    m_u: np.ndarray
    m_v: np.ndarray
    plain: bool  # no lens distortion and no box depth: the closed-form foot gain applies (:func:`head_gain`)
    lam: np.ndarray | None = None  # (Q, 1) the sets' lens when one holds one; None: no lens
    image_heads: np.ndarray | None = None  # (N, 2) the observed heads about the principal point, in the image (lens)
    radius_px: float = 1.0  # the lens's R


def camera_terms(rel_feet: np.ndarray, diff: np.ndarray, params: np.ndarray, radius_px: float = 1.0) -> CameraTerms:
    """:class:`CameraTerms` of ``params (Q, 6)`` for pairs ``rel_feet``, ``diff`` (N, 2) px (as :func:`head_errors`)."""
    f, pitch, roll, h = (slot(params, i) for i in (FOCAL, PITCH, ROLL, HEIGHT))
    lam, box = slot(params, DISTORTION), slot(params, BOX_DEPTH)
    distorted = bool(np.any(lam))
    image_heads = None
    if distorted:  # the foot undistorted; the head stays in the image (_image_head_errors distorts the prediction)
        image_heads = rel_feet - diff
        rel_feet = undistort_rel_px(rel_feet, lam, radius_px)
        diff = rel_feet - image_heads
    n = up_vector_cam(pitch[:, 0], roll[:, 0])
    nx, ny, nz = n[:, 0:1], n[:, 1:2], n[:, 2:3]
    d, m_u, m_v = foot_terms(rel_feet[..., 0], rel_feet[..., 1], f, nx, ny, nz)
    return CameraTerms(rel_feet, diff, f, h, box, (nx, ny, nz), d, m_u, m_v, not distorted and not np.any(box),
                       lam if distorted else None, image_heads, radius_px)


def head_errors(rel_feet: np.ndarray, diff: np.ndarray, params: np.ndarray, stature_m: float | np.ndarray,
                radius_px: float = 1.0, z_min: float = Z_MIN, terms: CameraTerms | None = None
                ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Head errors (u, v), their derivatives by the stature (u, v), each (Q, N), and validity (Q, N).

    rel_feet = feet - principal point and diff = feet - observed heads, (N, 2) px; params (Q, 6)
    (:mod:`.params` slots); stature_m: scalar, (N,) or (Q, N); radius_px: the distortion's radius
    (half-diagonal). Errors are predicted minus observed heads, px; derivatives px/m. A pair is
    valid when its foot ray meets the ground and its head depth ratio ``z`` exceeds ``z_min``.
    terms: :func:`camera_terms` of these arguments, when already computed.
    """
    t = camera_terms(rel_feet, diff, params, radius_px) if terms is None else terms
    u, v = t.rel_feet[..., 0], t.rel_feet[..., 1]
    k, dk, ok = _box_k(u, v, t.f, t.h, t.d, t.box, stature_m) if np.any(t.box) else (stature_m / t.h, 1.0 / t.h, True)
    z = 1.0 + k * t.n[2] * t.d
    valid = (t.d > RAY_EPS) & (z > z_min) & ok
    z = np.maximum(z, max(z_min, _Z_FLOOR))
    coef, dcoef = k / z, dk / (z * z)
    if t.lam is not None:
        return _image_head_errors(t, coef, dcoef, valid)
    return ((t.diff[..., 0] + coef * t.m_u, t.diff[..., 1] + coef * t.m_v), (dcoef * t.m_u, dcoef * t.m_v), valid)


def _image_head_errors(t: CameraTerms, coef: np.ndarray, dcoef: np.ndarray, valid: np.ndarray
                       ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray]:
    """:func:`head_errors` through a lens: the predicted head ``F + coef M`` (undistorted, Q x N) distorted into the
    image (``p_d = s p_u``, :func:`~rotavat_cli.geometry.lens.distort_scale`) minus the observed head there, and its
    derivative by the stature through the distortion's Jacobian ``s v + p_u (ds/drho) 2 (p_u . v) / R^2``. A head
    the lens has no image of is invalid (its error the undistorted prediction's, finite)."""
    move = np.stack([t.m_u, t.m_v], axis=-1)
    pred = t.rel_feet + coef[..., None] * move
    scale, dscale = distort_scale(pred, t.lam, t.radius_px)
    ok = np.isfinite(scale) & np.isfinite(dscale)
    scale, dscale = np.where(ok, scale, 1.0), np.where(ok, dscale, 0.0)
    err = pred * scale[..., None] - t.image_heads
    v = dcoef[..., None] * move
    along = np.sum(pred * v, axis=-1) * (2.0 / t.radius_px**2)
    d_err = scale[..., None] * v + pred * (dscale * along)[..., None]
    return (err[..., 0], err[..., 1]), (d_err[..., 0], d_err[..., 1]), valid & ok


def head_gain(rel_feet: np.ndarray, params: np.ndarray, stature_m: float | np.ndarray,
              terms: CameraTerms | None = None) -> np.ndarray | None:
    """How each predicted head moves with its foot pixel, in closed form: ``d head / d foot`` (Q, N, 2, 2),
    rows (u, v) of the head, columns (u, v) of the foot; None when the parameter sets hold a lens distortion or a
    box depth (then :func:`head_errors` by finite differences says it). terms: :func:`camera_terms` of
    ``rel_feet`` and ``params``, when already computed.

    With ``d`` and ``M`` of the module docstring, ``d' = -n_xy / f`` and ``c = k / z``: the head is
    ``F + c M``, so ``dH/dF = I + M (dc/dF)^T + c dM/dF`` with ``dM/dF = (f n_xy - n_z F) d'^T - d n_z I`` and
    ``dc/dF = -c^2 n_z d'`` (``k = S / h`` does not depend on the foot).
    """
    t = camera_terms(rel_feet, np.zeros_like(rel_feet), params) if terms is None else terms
    if not t.plain:
        return None
    f, h, (nx, ny, nz), d, m_u, m_v = t.f, t.h, t.n, t.d, t.m_u, t.m_v
    u, v = t.rel_feet[..., 0], t.rel_feet[..., 1]
    k = stature_m / h
    z = np.maximum(1.0 + k * nz * d, _Z_FLOOR)
    c = k / z
    dd = (-nx / f, -ny / f)  # d d / d (u, v), (Q, 1) each
    a = (f * nx - nz * u, f * ny - nz * v)  # M / d, (Q, N) each
    gain = np.empty((2, 2) + np.broadcast(u, c).shape)  # components first: each written whole, not strided
    d_nz = d * nz
    for i in range(2):  # head row (u, v)
        m_c2_nz = (m_u, m_v)[i] * c * c * nz  # the same products, in the same order, as m_i * c * c * nz * dd[j]
        for j in range(2):  # foot column (u, v)
            dm = a[i] * dd[j] - (d_nz if i == j else 0.0)
            gain[i, j] = (1.0 if i == j else 0.0) - m_c2_nz * dd[j] + c * dm
    return np.moveaxis(gain, (0, 1), (-2, -1))  # (Q, N, 2, 2), a view


def _box_k(u: np.ndarray, v: np.ndarray, f: np.ndarray, h: np.ndarray, d: np.ndarray, box: np.ndarray,
           stature_m: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``k``, ``dk/dS`` and validity (Q, N) when the head stands ``box`` m beyond the foot, away from the camera.

    With ``rho`` the foot's ground distance over the camera height, the head point
    ``G + b e + S n`` (``e`` the horizontal direction away from the camera) projects like an
    upright person with ``k = (S rho + b) / (h rho + b)`` (``k = S / h`` when ``b = 0``).
    """
    rho = np.sqrt(np.maximum(((u * u + v * v) / (f * f) + 1.0) / np.maximum(d, RAY_EPS) ** 2 - 1.0, 0.0))
    denom = h * rho + box
    safe = np.where(denom > 0, denom, 1.0)
    return (stature_m * rho + box) / safe, rho / safe, denom > 0


def predict_heads_px(feet_px: np.ndarray, focal_px: np.ndarray | float, pitch_rad: np.ndarray | float,
                     roll_rad: np.ndarray | float, height_m: np.ndarray | float, principal_point: tuple | np.ndarray,
                     person_height_m: np.ndarray | float) -> np.ndarray:
    """Predicted head pixels (..., N, 2) of people standing on feet_px (N, 2); NaN where invalid.

    Camera parameters broadcast over leading dimensions ``(...)``; ``person_height_m`` is a
    scalar or (N,). Invalid: the foot ray misses the ground or the head is behind the camera.
    """
    feet = np.asarray(feet_px, dtype=np.float64)
    f, pitch, roll, h = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64)
                                              for v in (focal_px, pitch_rad, roll_rad, height_m)))
    params = np.zeros((f.size, N_PARAMS))
    for index, value in ((FOCAL, f), (PITCH, pitch), (ROLL, roll), (HEIGHT, h)):
        params[:, index] = value.ravel()
    rel_feet = feet - np.asarray(principal_point, dtype=np.float64)
    (e_u, e_v), _, valid = head_errors(rel_feet, np.zeros_like(feet), params,
                                       np.asarray(person_height_m, dtype=np.float64), z_min=0.0)
    heads = np.where(valid[..., None], feet + np.stack([e_u, e_v], axis=-1), np.nan)
    return heads.reshape(f.shape + feet.shape)
