"""Camera calibration from the people a static camera sees (docs/calibration.md).

Modules, from the model up:

- :mod:`.params`: the parameter vector's named slots (``FOCAL``, ``PITCH``, ...), its refined form, bounds;
- :mod:`.model`: the person model, a head pixel predicted in closed form from its foot pixel;
- :mod:`.residuals`: the registry of residual kinds (``full``, ``vertical``): what is compared;
- :mod:`.grid`: the paper's grid (fast kernel + exact re-scoring) and the refinement's seeds;
- :mod:`.priors`: what the fit assumes where the people do not tell (the lens prior, weak pitch/height bounds);
- :mod:`.objective`: the refinement's weighted, track-profiled residuals, priors and bodies' axis;
- :mod:`.refine`: robust least squares with outlier rejection from several starts;
- :mod:`.uncertainty`: standard deviations, correlations, what determined each parameter, warnings;
- :mod:`.plausibility`: is the result a camera at all (``fit.implausible``);
- :mod:`.options`: :class:`CalibrateOptions`, every option (the ``calibrate`` config section);
- :mod:`.inputs`: the pairs checked, the point model resolved, the priors chosen, hopeless scenes refused;
- :mod:`.fit`: :func:`fit_camera`, :func:`calibrate`, :func:`fit_per_frame`, :class:`CalibrationResult`;
- :mod:`.pairs`: every frame's foot/head pixels, with each person's posture and body axis;
- :mod:`.sequence`: :func:`calibrate_sequence`, a whole sequence: the focal policy, who stands, who stands still.

>>> import numpy as np
>>> from rotavat_cli.calibration import CalibrateOptions, fit_camera, predict_heads_px
>>> feet = np.array([[100.0, 300.0], [320.0, 400.0], [500.0, 350.0], [250.0, 460.0], [600.0, 420.0]])
>>> heads = predict_heads_px(feet, 500.0, np.deg2rad(30.0), 0.0, 5.0, (320.0, 240.0), 1.7)
>>> res = fit_camera(feet, heads, (640, 480), CalibrateOptions(focal_px=500.0, residual="vertical"))
>>> round(res.camera.height_m, 2), res.residual   # exact pairs; the weak priors move it by 0.5 mm
(5.0, 'vertical')
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".fit": ("CalibrationResult", "PerFrameSummary", "calibrate", "fit_camera", "fit_per_frame"),
    ".grid": ("GridFit", "GridSpec", "grid_costs", "paper_grid_search", "reference_cell_costs"),
    ".inputs": ("BOX_COLUMN_TOL_PX", "box_derived"),
    ".model": ("predict_heads_px",),
    ".options": ("FOCAL_PRIORS", "METHODS", "POINTS", "SECTION_RULES", "CalibrateOptions"),
    ".residuals": ("RESIDUAL_KINDS", "RESIDUALS", "ResidualKind", "residual_kind"),
    ".sequence": ("FOCAL_POLICIES", "SequenceCalibration", "calibrate_sequence", "declared_focal"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
