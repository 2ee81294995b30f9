"""Every option of a calibration, validated in one place: :class:`CalibrateOptions`.

The first fields are the ``calibrate`` section of ``configs/default.yaml``, one field per key and
named like it; the YAML is the source of their defaults, and a test checks
``CalibrateOptions() == CalibrateOptions.from_config(default_config()["calibrate"])`` so the
dataclass cannot drift from it. The last fields are not in the config: the model's pixel noise
and the sds of what it assumes without fitting (Python callers and tests set them).

>>> from rotavat_cli.settings.config import default_config
>>> CalibrateOptions.from_config(default_config()["calibrate"]) == CalibrateOptions()
True
>>> CalibrateOptions(method="grid", distortion=True)
Traceback (most recent call last):
...
ValueError: distortion and points='boxes' need method 'refine' (the grid is the paper's model)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import ClassVar

import numpy as np

from ..errors import InputError
from ..geometry.focal import focal_px_from_35mm
from ..geometry.lens import MAX_DISTORTION
from ..settings.option_rules import Rule, check_fields
from .grid import GridSpec
from .priors import FOCAL_PRIORS
from .residuals import RESIDUALS

__all__ = ["METHODS", "POINTS", "FOCAL_PRIORS", "CalibrateOptions", "SECTION_RULES"]

METHODS = ("grid", "refine")
POINTS = ("auto", "landmarks", "boxes")  # auto: boxes when every pair's head is in its foot's column
_NOT_IN_CONFIG = {"config": False}  # field metadata: an option Python sets, absent from configs/default.yaml
_OPTIONAL = {"focal_px", "focal_mm", "camera_height_m", "principal_point_sd_px", "fov_prior_deg", "pitch_deg",
             "lens_distortion", "lens_distortion_sd"}  # None: not given
_POSITIVE = Rule(low=0, open_low=True)
_NON_NEGATIVE = Rule(low=0)


@dataclass(frozen=True)
class CalibrateOptions:
    """How to calibrate (docs/calibration.md). Sequence-level options (``estimate_focal``,
    ``per_frame``) are read by :func:`~rotavat_cli.calibration.calibrate_sequence` only."""

    # ---- the ``calibrate`` config section (defaults: configs/default.yaml) ----
    method: str = "refine"  # grid (the paper, exactly) | refine (grid seeds + robust refinement)
    person_height_m: float = 1.70  # mean stature sole -> crown
    person_height_sd_m: float = 0.07  # spread of the stature prior (refine)
    residual: str = "full"  # a registered residual kind (residuals.RESIDUALS); boxes always use the row
    points: str = "auto"  # auto | landmarks (mid-sole, crown) | boxes (bottom-/top-centre of person boxes)
    # Box depth, m: a box's bottom is the walker's lowest image point, the nearest foot's toe or heel
    # (half a foot length, 0.13 m, plus on average ~0.1 m of stride toward the camera); its top is the
    # head's silhouette, ~0.03 m beyond the crown for a camera looking down.
    box_depth_m: float = 0.25
    # refine: also fit one-parameter (division model) radial lens distortion, kept only when the pairs tell it from
    # none (fit.LENS_SIGNIFICANCE). None: tried only for few pairs of people of measured stature (fit._tries_the_lens).
    distortion: bool | None = None
    estimate_roll: bool = True  # refine only; the paper fixes roll at 0
    estimate_focal: bool = False  # sequences: estimate f even when the sequence's focal is the camera's own
    focal_px: float | None = None  # fix the focal length (px); None: estimated
    focal_mm: float | None = None  # fix it as a 35 mm-equivalent focal (mm), converted at the image size; not with focal_px
    camera_height_m: float | None = None  # known camera height (m): fixes the scale, the mean stature is estimated
    pitch_deg: float | None = None  # fix the pitch (deg, + = looking down); None: estimated
    principal_point: tuple[float, float] | None = None  # (cx, cy) px; None = the sequence's, else the image centre
    focal_prior: str = "lens"  # refine: lens (the prior of real lenses, priors.py) | none (the people alone)
    fov_prior_deg: float | None = None  # mean of your own prior on the vertical field of view (replaces the lens prior)
    standing_only: bool = True  # sequences: leave out people whose joints say they sit, kneel or bend
    body_axes: bool = True  # refine: standing bodies' own vertical where the pairs leave the pitch undetermined
    tracks: tuple[int, ...] | None = None  # sequences: calibrate from these person_ids only (None: everyone)
    per_frame: bool = False  # sequences: also calibrate every frame alone and report the spread
    grid: GridSpec = GridSpec()  # the paper's search grid (calibrate.grid)
    # A known lens: its division-model coefficient (geometry/lens.py), from a lens profile or the scene's straight
    # lines (calibrate --lens-lines, calibration/plumb_lines.py); the pairs are undistorted before the fit and the
    # camera carries it (calibration/given_lens.py). None: no lens, unless ``distortion`` fits one.
    lens_distortion: float | None = None
    # ---- not in the config ----
    noise_px: float = field(default=2.0, metadata=_NOT_IN_CONFIG)  # pixel noise of the points (refine weights)
    fov_prior_sd_deg: float = field(default=10.0, metadata=_NOT_IN_CONFIG)
    # Where a given focal (focal_px or focal_mm) came from, for the fit block's focal_source (the CLI: "--focal",
    # "EXIF FocalLengthIn35mmFilm 26 mm of IMG.jpg"); None: named after the option (given_focal_source).
    focal_source: str | None = field(default=None, metadata=_NOT_IN_CONFIG)
    # Assumed-but-unknown quantities, propagated into the reported std: the principal point per axis
    # (None: 2% of the larger image side, or 0 when principal_point is given), radial distortion unless
    # fitted (corner displacement over the half-diagonal), the people's mean stature (not when
    # camera_height_m is given) and the box depth (the sd spans standing people, 0.15 m, to long
    # strides, 0.35 m).
    principal_point_sd_px: float | None = field(default=None, metadata=_NOT_IN_CONFIG)
    distortion_sd: float = field(default=0.01, metadata=_NOT_IN_CONFIG)
    person_height_mean_sd_m: float = field(default=0.04, metadata=_NOT_IN_CONFIG)
    box_depth_sd_m: float = field(default=0.10, metadata=_NOT_IN_CONFIG)
    max_rounds: int = field(default=6, metadata=_NOT_IN_CONFIG)  # rejection rounds of the full refinement
    # Standing bodies' axes (docs/calibration.md, "What the bodies know"): how far an HPS body's axis
    # may be from the true vertical, and the pitch std of the pairs (with the priors) above which
    # they are added: the pairs leave the pitch undetermined (plausibility.MAX_ANGLE_SD_DEG).
    body_axis_sd_deg: float = field(default=10.0, metadata=_NOT_IN_CONFIG)
    body_engage_pitch_sd_deg: float = field(default=10.0, metadata=_NOT_IN_CONFIG)
    # The foot's pixel noise carried into each head's error (objective.pair_covariance: errors in variables);
    # False gives the weights of earlier versions (benchmarks/bench_consistency.py shows what that costs).
    errors_in_variables: bool = field(default=True, metadata=_NOT_IN_CONFIG)
    # The few-pairs policy (fit._few_pairs_policy): with fewer than fit.FEW_PAIRS pairs, the roll held near 0 by the
    # mounting prior when the pairs cannot determine it. On by default (issue 35: benchmarks/bench_reference.py, one
    # reference person, no worse than holding the roll at 0 for any reference and than the fits without it);
    # False gives the fits of earlier versions.
    few_pairs: bool = field(default=True, metadata=_NOT_IN_CONFIG)
    # A given lens's own uncertainty (its coefficient's sd: the plumb-line fit's, or the default distortion_sd for a
    # profile) and where it came from, for the fit block's ``lens`` ("given", "lines FILE").
    lens_distortion_sd: float | None = field(default=None, metadata=_NOT_IN_CONFIG)
    lens_source: str | None = field(default=None, metadata=_NOT_IN_CONFIG)

    RULES: ClassVar[dict[str, Rule]] = {  # every option's bounds and names (rotavat_cli/settings/option_rules.py)
        "method": Rule(names=METHODS), "residual": Rule(names=RESIDUALS), "points": Rule(names=POINTS),
        "focal_prior": Rule(names=FOCAL_PRIORS),
        "person_height_m": Rule(low=0.5, high=3.0, unit="m"), "person_height_sd_m": Rule(low=0, high=1.0, unit="m"),
        "box_depth_m": Rule(low=-1.0, high=2.0, unit="m"), "focal_px": Rule(low=1e-3, high=1e7, unit="px"),
        "focal_mm": Rule(low=1e-3, high=1e5, unit="mm"),
        "camera_height_m": Rule(low=0.01, high=1e5, unit="m"), "pitch_deg": Rule(low=-89.9, high=89.9, unit="deg"),
        "fov_prior_deg": Rule(low=0.1, high=179.9, unit="deg"), "principal_point": Rule(low=-1e6, high=1e6, unit="px"),
        "lens_distortion": Rule(low=-MAX_DISTORTION, high=MAX_DISTORTION),
        # not in the config
        "noise_px": _POSITIVE, "fov_prior_sd_deg": _POSITIVE, "distortion_sd": _NON_NEGATIVE,
        "person_height_mean_sd_m": _NON_NEGATIVE, "principal_point_sd_px": _NON_NEGATIVE,
        "body_axis_sd_deg": Rule(low=0, high=90, open_low=True, unit="deg"), "body_engage_pitch_sd_deg": _NON_NEGATIVE,
        "box_depth_sd_m": _NON_NEGATIVE, "lens_distortion_sd": _NON_NEGATIVE,
    }

    def __post_init__(self) -> None:
        """Normalise numbers to float, flags to bool, the principal point to a tuple; ValueError for a bad option."""
        if self.principal_point is not None and (isinstance(self.principal_point, (str, bytes))
                                                 or len(np.shape(self.principal_point)) != 1
                                                 or len(self.principal_point) != 2):
            raise ValueError(f"principal_point must be (cx, cy) in pixels, got {self.principal_point!r}")
        check_fields(self, self.RULES)
        if self.focal_px is not None and self.focal_mm is not None:
            raise ValueError("focal_px and focal_mm both fix the focal length: give one, not both")
        if self.focal_source is not None and (not isinstance(self.focal_source, str)
                                              or (self.focal_px is None and self.focal_mm is None)):
            raise ValueError(f"focal_source names where a given focal came from: a text with focal_px or focal_mm, "
                             f"got {self.focal_source!r}")
        if self.distortion and self.lens_distortion is not None:
            raise ValueError("distortion fits the lens and lens_distortion gives it: use one, not both")
        if self.lens_source is not None and (not isinstance(self.lens_source, str) or self.lens_distortion is None):
            raise ValueError(f"lens_source names where a given lens came from: a text with lens_distortion, "
                             f"got {self.lens_source!r}")
        if self.method == "grid" and (self.distortion or self.points == "boxes"):
            raise ValueError("distortion and points='boxes' need method 'refine' (the grid is the paper's model)")
        if not isinstance(self.grid, GridSpec):
            raise TypeError(f"grid must be a GridSpec, got {type(self.grid).__name__}")
        for name, rule in self.RULES.items():
            value = getattr(self, name)
            if rule.names or name == "principal_point" or (value is None and name in _OPTIONAL):
                continue
            if value is None:
                raise ValueError(f"{name} must be a number, got None")
            object.__setattr__(self, name, float(value))
        if self.principal_point is not None:
            try:
                pp = np.asarray(self.principal_point, dtype=np.float64)
            except (TypeError, ValueError):
                pp = np.full(0, np.nan)
            if pp.shape != (2,) or not np.all(np.isfinite(pp)):
                raise ValueError(f"principal_point must be (cx, cy) in pixels, got {self.principal_point!r}")
            object.__setattr__(self, "principal_point", (float(pp[0]), float(pp[1])))
        if self.tracks is not None:
            ids = np.asarray(self.tracks)
            if ids.ndim != 1 or len(ids) == 0 or not (np.issubdtype(ids.dtype, np.integer) or ids.dtype == object
                                                      and all(isinstance(i, (int, np.integer)) for i in ids)):
                raise ValueError(f"tracks must be a non-empty list of person ids (integers), got {self.tracks!r}")
            object.__setattr__(self, "tracks", tuple(sorted({int(i) for i in ids})))
        rounds = self.max_rounds
        if isinstance(rounds, bool) or not isinstance(rounds, (int, np.integer)) or rounds < 1:
            raise ValueError(f"max_rounds must be a positive integer, got {self.max_rounds!r}")
        object.__setattr__(self, "max_rounds", int(self.max_rounds))
        if self.distortion is not None:
            if not isinstance(self.distortion, (bool, np.bool_)):
                raise ValueError(f"distortion must be true, false or null (tried when the pairs are few), "
                                 f"got {self.distortion!r}")
            object.__setattr__(self, "distortion", bool(self.distortion))
        for name in ("estimate_roll", "estimate_focal", "per_frame", "standing_only", "body_axes",
                     "errors_in_variables", "few_pairs"):
            object.__setattr__(self, name, bool(getattr(self, name)))

    def given_focal_px(self, image_size: tuple[int, int]) -> float | None:
        """The focal (px) the options fix on an image of ``image_size`` (W, H): ``focal_px``, else ``focal_mm``
        converted (:func:`~rotavat_cli.geometry.focal.focal_px_from_35mm`), else None (not given).

        >>> CalibrateOptions(focal_mm=26.0).given_focal_px((4032, 3024)) == focal_px_from_35mm(26.0, (4032, 3024))
        True
        """
        if self.focal_px is not None:
            return self.focal_px
        return None if self.focal_mm is None else focal_px_from_35mm(self.focal_mm, image_size)

    def given_focal_source(self, px_name: str = "calibrate.focal_px", mm_name: str = "calibrate.focal_mm") -> str | None:
        """Where the given focal came from (the fit block's ``focal_source``): ``focal_source``, else the option
        that gave it, named ``px_name`` or ``mm_name`` (the CLI: ``--focal``, ``--focal-mm``); None when no focal
        is given.

        >>> CalibrateOptions(focal_mm=26.0).given_focal_source(), CalibrateOptions(focal_px=900.0).given_focal_source()
        ('calibrate.focal_mm 26 (35 mm equivalent)', 'calibrate.focal_px')
        """
        if self.focal_source is not None or (self.focal_px is None and self.focal_mm is None):
            return self.focal_source
        return px_name if self.focal_px is not None else f"{mm_name} {self.focal_mm:g} (35 mm equivalent)"

    def replace(self, **changes) -> CalibrateOptions:
        """A copy with some options changed (validated); TypeError naming an unknown option."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise TypeError(f"unknown calibration option(s) {', '.join(unknown)} (options: "
                            f"{', '.join(f.name for f in fields(self))})")
        return replace(self, **changes)

    @classmethod
    def config_keys(cls) -> tuple[str, ...]:
        """The fields read from the ``calibrate`` config section, in order."""
        return tuple(f.name for f in fields(cls) if f.metadata.get("config", True))

    @classmethod
    def from_config(cls, section: Mapping) -> CalibrateOptions:
        """Options from a whole ``calibrate`` config section (every key of it, no other);
        InputError (exit 2) naming the key or the problem."""
        keys = cls.config_keys()
        unknown, missing = sorted(set(section) - set(keys)), [k for k in keys if k not in section]
        if unknown or missing:
            raise InputError("calibrate: " + "; ".join(
                ([f"unknown key(s) {', '.join(unknown)}"] if unknown else [])
                + ([f"missing key(s) {', '.join(missing)}"] if missing else [])))
        try:
            grid = GridSpec(**section["grid"])
        except (TypeError, ValueError) as exc:
            raise InputError(str(exc) if "calibrate.grid" in str(exc) else f"calibrate.grid: {exc}") from None
        try:
            return cls(**{**section, "grid": grid})
        except (TypeError, ValueError) as exc:
            raise InputError(f"calibrate: {exc}") from None


# the ``calibrate`` config section's keys and their rules (its ``grid`` sub-section's as ``grid.<key>``)
SECTION_RULES: dict[str, Rule] = {**CalibrateOptions.RULES, **{f"grid.{key}": rule for key, rule in GridSpec.RULES.items()}}
