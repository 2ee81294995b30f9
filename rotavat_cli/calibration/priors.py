"""What the calibration assumes where the people do not tell: documented priors on the camera.

People at one depth (one person walking across the view, a group photo) cannot fix the focal
length, and a person standing still cannot fix the pitch or the camera height either. Instead of
refusing (or answering with a camera at the end of a search range), the refinement is a maximum
a posteriori estimate: the people's pairs plus weak priors on the internal parameters
(:mod:`.params`: ``log f``, pitch, roll, ``log h``). Where the people determine a parameter the prior
moves it by a negligible amount (its information is a few percent of theirs); where they do not,
the answer is the prior's, and the fit says so (``fit.determined_by``).

The priors, on the internal parameters:

- focal, the *lens prior*: ``log(f / D)`` (``D`` the image diagonal) about log 0.75, a Student-t of
  3 degrees of freedom with the curvature of a normal of sd 0.30 at its centre (:func:`student_row`:
  where it alone speaks its std is 30%; a lens the people put far from the median is pulled 2-3x
  less than by a normal). Real lenses: phones' main cameras 0.65-0.75 D, webcams 0.62-0.73 D,
  compacts ~0.71 D, surveillance cameras 0.8-1.25 D, wide-angle (2.8 mm) surveillance lenses of
  100 deg horizontally ~0.35 D; +-2 sd spans 0.41-1.37 D, +-3 sd 0.30-1.84 D. A 2.9 deg field of
  view, 4D-Humans' focal rule, is +10 sd: an HPS tool's rule is never a prior;
- pitch: N(15 deg, 25 deg). Handheld cameras look about level (-5..15 deg), surveillance cameras
  down (10-60 deg): a bound, not an opinion;
- roll: N(0 deg, 10 deg). Cameras are mounted and held nearly level. Where few pairs cannot determine the
  roll (:func:`~.fit.fit_camera`'s few-pairs policy), N(0, 1 deg): a mounted camera levelled by eye
  (``MOUNTED_ROLL_SD_DEG``);
- height: ``log h`` ~ N(log 3 m, 0.8). Handheld 1.2-2 m, surveillance 2.5-15 m (+-2 sd: 0.6-15 m);
- lens (when fitted: ``--distortion``, or by default from fewer than 50 pairs of people of measured stature,
  ``MEASURED_STATURE_SD_M``): the division coefficient ~ N(0, 0.15) (``DISTORTION_PRIOR_SD``).

With ``--camera-height M`` the height is known and the people's mean stature ``S`` is estimated
instead; since the model sees only ``S / h``, that is the height slot with the prior
``log h ~ N(log M, sd_S / S0)``: the group's mean stature ``N(S0, 0.10 m)`` (adult means differ by
country and sex mix by +-8 cm, children and HPS size bias add more), reported as a stature.
``--fov-prior DEG`` replaces the lens prior by the user's own on the vertical field of view, and
``focal_prior="none"`` removes it (the people alone then decide the focal, or the fit refuses).

>>> p = default_priors((1920, 1080))
>>> round(float(np.exp(p.mean[FOCAL])), 1), round(float(np.rad2deg(p.mean[PITCH])), 1)
(1652.2, 15.0)
>>> rows = p.rows(to_internal(param_vector(focal=1652.2, pitch=np.deg2rad(40.0), roll=0.0, height=3.0))[None],
...               param_vector(focal=True, pitch=True, roll=True, height=True, dtype=bool))
>>> np.round(rows, 3).tolist()        # (pitch - 15 deg) / 25 deg = 1; the rest at their means
[[0.0, 1.0, 0.0, 0.0]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import DISTORTION, FOCAL, HEIGHT, N_PARAMS, PITCH, ROLL, param_vector, to_internal  # noqa: F401 (to_internal: the doctest)

__all__ = ["FOCAL_PRIORS", "LENS_FOCAL_OVER_DIAGONAL", "LENS_LOG_SD", "LENS_DOF", "student_row", "PITCH_PRIOR_DEG", "ROLL_PRIOR_SD_DEG",
           "MOUNTED_ROLL_SD_DEG", "MEASURED_STATURE_SD_M", "LEAN_SD_DEG", "DISTORTION_PRIOR_SD", "HEIGHT_PRIOR_M", "HEIGHT_LOG_SD", "MEAN_STATURE_SD_M", "Priors", "default_priors", "lens_range_px"]

FOCAL_PRIORS = ("lens", "none")  # calibrate.focal_prior: the lens prior, or none (the people alone)
LENS_FOCAL_OVER_DIAGONAL = 0.75  # median focal of real lenses / image diagonal (table above)
LENS_LOG_SD = 0.30  # sd of log(f / D) (the curvature at the median; the lens prior is a Student-t, LENS_DOF)
LENS_DOF = 3.0  # its degrees of freedom: heavy tails, so people who determine a wide or long lens are not pulled back
PITCH_PRIOR_DEG = (15.0, 25.0)  # mean, sd
ROLL_PRIOR_SD_DEG = 10.0  # mean 0
# A fitted lens's division coefficient, mean 0 (the corner's relative displacement): surveillance and phone lenses
# move the corner by 0-30% (barrel), pincushion is rare; +-2 sd spans +-0.3. Only a fit with --distortion uses it;
# from a few tens of clicks it keeps the lens from trading itself for the focal and the pitch (a far-only reference
# fitted +0.29 to a pinhole camera and measured everyone 10 cm off: benchmarks/bench_reference.py).
DISTORTION_PRIOR_SD = 0.15
# A stature known this well (sd, m) is a measured one (a tape-measured reference: --height-sd 0.01); only then do a few
# pairs carry the lens (the few-pairs policy tries it: fit._tries_the_lens). A 25% barrel lens changes a person's
# image length by a few percent, about 5 cm of stature; the population's 7 cm spread per person hides it, and on
# twenty people of unknown stature at two depths --distortion kept a spurious lens (up to +0.19, the pitch 1.3 deg
# off) in 2 of 20 draws, 3 std from none (tests/test_lens_fit_policy.py): there the lens's std is too small.
MEASURED_STATURE_SD_M = 0.02
# The few-pairs policy's roll prior: the spread of mounted cameras' roll. An installer levelling by eye leaves it within
# 1-2 deg (a 2 deg roll tilts a doorframe 3.5 cm per metre, which one sees): +-2 sd = +-2 deg, sd 1 deg. Measured
# (benchmarks/bench_reference.py, one reference person, cameras' roll uniform in +-2 deg, i.e. sd 1.15 deg): the other
# subjects' mean |error| 2.93 cm with sd 1 deg, 2.95 with 2 deg, 3.03 with 0.5 deg, 2.97 with the roll free, 3.64 held
# at 0; with the roll within +-0.5 deg, 2.86, 2.92, 2.75, 2.94 and 2.75 cm (docs/calibration.md, "Few pairs: one
# reference person"). "Hold roll at 0" is this prior's limit sd -> 0; the prior, unlike holding, lets pairs that do
# determine the roll override it.
MOUNTED_ROLL_SD_DEG = 1.0
# A walking person's crown is off their mid-sole's vertical by a few cm (a lean of the whole person that persists over
# a walk, and the sway of each step): 3 cm over a 1.7 m stature, 1.0 deg. The head columns of one person's clicks
# share that lean, so however many clicks there are, their roll is no better than it; P people average it to 1/sqrt(P).
LEAN_SD_DEG = 1.0
HEIGHT_PRIOR_M = 3.0  # median camera height
HEIGHT_LOG_SD = 0.8  # sd of log h
MEAN_STATURE_SD_M = 0.10  # the people's mean stature, when the camera height is given
_CAMERA_SLOTS = param_vector(focal=True, pitch=True, roll=True, height=True, dtype=bool)  # the slots priors cover


@dataclass(frozen=True)
class Priors:
    """Independent normal priors on the internal parameters: ``mean (6,)`` and ``sd (6,)`` (inf: no prior).

    ``focal_kind`` names the focal's prior in messages: "lens", "fov" (the user's field-of-view
    prior) or "none"; ``height_kind``: "camera" (where cameras are mounted) or "stature" (the
    camera height is known and the prior is on the people's mean stature).
    """

    mean: np.ndarray
    sd: np.ndarray
    focal_kind: str = "lens"
    height_kind: str = "camera"

    def rows(self, x_internal: np.ndarray, free: np.ndarray) -> np.ndarray:
        """Prior residuals (Q, R) of internal parameter sets ``x_internal (Q, 6)``: one row per free slot with a
        prior; the lens prior's row is a Student-t's (:func:`student_row`), the others normal."""
        slots = self.slots(free)
        z = (x_internal[:, slots] - self.mean[slots]) / self.sd[slots]
        if self.focal_kind == "lens" and FOCAL in slots:
            k = int(np.flatnonzero(slots == FOCAL)[0])
            z[:, k] = student_row(z[:, k], LENS_DOF)
        return z

    def slots(self, free: np.ndarray) -> np.ndarray:
        """Indices of the free slots that have a prior."""
        return np.flatnonzero(np.asarray(free, bool) & np.isfinite(self.sd))

    def cover(self, free: np.ndarray) -> bool:
        """True when every free camera slot (focal, pitch, roll, height; ``free`` (6,) bool) has a prior: the
        posterior then has a mode whatever the pairs are, and one usable pair is enough."""
        return bool(np.all(np.isfinite(self.sd[np.asarray(free, bool) & _CAMERA_SLOTS])))

    def with_sd(self, slot: int, sd: float) -> "Priors":
        """The same priors with the sd of ``slot`` (internal units) replaced."""
        sd_all = self.sd.copy()
        sd_all[slot] = sd
        return Priors(self.mean, sd_all, self.focal_kind, self.height_kind)

    def without_focal(self) -> "Priors":
        """The same priors with none on the focal."""
        sd = self.sd.copy()
        sd[FOCAL] = math.inf
        return Priors(self.mean, sd, "none", self.height_kind)


def student_row(z: np.ndarray, dof: float) -> np.ndarray:
    """Residual row (...) whose square is a Student-t's ``-2 log density`` (up to a constant) with ``dof``
    degrees of freedom, for standardised values ``z`` (...): ``sign(z) sqrt((dof+1) log(1 + z^2 c / dof))``
    with ``c = dof / (dof + 1)``, so that its curvature at 0 is a unit normal's (the same sd where the
    prior alone speaks) while far values pull less (a lens the people put 2.2 sd from the median is
    pulled 2.5x less than by a normal prior)."""
    c = dof / (dof + 1.0)
    return np.sign(z) * np.sqrt((dof + 1.0) * np.log1p(z * z * c / dof))


def default_priors(image_size: tuple[int, int], *, focal_prior: str = "lens",
                   fov_prior_deg: tuple[float, float] | None = None, camera_height_m: float | None = None,
                   person_height_m: float = 1.70) -> Priors:
    """The priors of a calibration (module docstring) for an image of ``image_size (W, H)`` px.

    fov_prior_deg: (mean, sd) of the vertical field of view, the user's own focal prior (replaces the
    lens prior); focal_prior: "lens" or "none"; camera_height_m: a known camera height, which turns
    the height prior into one on the people's mean stature about ``person_height_m``.
    """
    if focal_prior not in FOCAL_PRIORS:
        raise ValueError(f"focal_prior must be one of {FOCAL_PRIORS}, got {focal_prior!r}")
    W, H = (float(v) for v in image_size)
    mean = param_vector(focal=math.log(LENS_FOCAL_OVER_DIAGONAL * math.hypot(W, H)),
                        pitch=math.radians(PITCH_PRIOR_DEG[0]), roll=0.0, height=math.log(HEIGHT_PRIOR_M))
    sd = np.full(N_PARAMS, math.inf)
    sd[[FOCAL, PITCH, ROLL, HEIGHT, DISTORTION]] = (LENS_LOG_SD, math.radians(PITCH_PRIOR_DEG[1]),
                                                    math.radians(ROLL_PRIOR_SD_DEG), HEIGHT_LOG_SD, DISTORTION_PRIOR_SD)
    focal_kind, height_kind = focal_prior, "camera"
    if fov_prior_deg is not None:  # the user's prior on the vertical field of view, as a log-focal prior
        fov_mean, fov_sd = fov_prior_deg
        mean[FOCAL] = math.log(H / (2.0 * math.tan(math.radians(fov_mean) / 2.0)))
        # d log f / d fov = -1 / sin(fov) (radians): the fov's sd as a log-focal sd
        sd[FOCAL] = math.radians(fov_sd) / math.sin(math.radians(fov_mean))
        focal_kind = "fov"
    elif focal_prior == "none":
        sd[FOCAL] = math.inf
    if camera_height_m is not None:
        mean[HEIGHT] = math.log(camera_height_m)
        sd[HEIGHT] = MEAN_STATURE_SD_M / person_height_m
        height_kind = "stature"
    return Priors(mean, sd, focal_kind, height_kind)


def lens_range_px(image_size: tuple[int, int], n_sd: float = 3.0) -> tuple[float, float]:
    """The lens prior's focal range (px) within ``n_sd`` standard deviations of its median."""
    centre = LENS_FOCAL_OVER_DIAGONAL * math.hypot(*(float(v) for v in image_size))
    return centre * math.exp(-n_sd * LENS_LOG_SD), centre * math.exp(n_sd * LENS_LOG_SD)
