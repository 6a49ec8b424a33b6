"""Kinematics of the saddle from tracked markers (thesis chapters 5-6).

The stages, in the order the pipeline runs them:

- :mod:`.smoothing`: robust local regression (rloess), gap bridging and depth regularisation;
- :mod:`.period`: the stride period and the analysis window of whole strides;
- :mod:`.frames`: the motion reference frame (travel, gravity) and the change to it;
- :mod:`.registration`: the static-shot marker model fitted rigidly to every frame;
- :mod:`.curve_fits`, :mod:`.goodness_of_fit` and :mod:`.fitting`: curve fits of every marker
  coordinate, their goodness of fit and uncertainty, and their analytic derivatives;
- :mod:`.rigid_body`: angular velocity and acceleration of the marker triangle;
- :mod:`.saddle_point`: position, velocity and acceleration of the invisible saddle point.

The names are imported on first use (PEP 562): ``estimate_period`` (numpy only) then does not pull
scipy's signal, stats and optimize in for a command that needs only the period.
"""

from __future__ import annotations

import importlib

# name -> the submodule defining it
_WHERE = {
    "span_points": "smoothing",
    "rloess": "smoothing",
    "bridge_gaps": "smoothing",
    "regularize_depth": "smoothing",
    "estimate_period": "period",
    "analysis_window": "period",
    "CAMERA_DOWN": "frames",
    "MotionFrame": "frames",
    "plumb_gravity": "frames",
    "travel_velocity": "frames",
    "motion_frame": "frames",
    "to_motion_frame": "frames",
    "vectors_to_motion_frame": "frames",
    "Registration": "registration",
    "layout_ratio": "registration",
    "check_marker_layout": "registration",
    "marker_model": "registration",
    "register_rigid": "registration",
    "broken_distance_samples": "registration",
    "CRITERIA": "goodness_of_fit",
    "GoodnessOfFit": "goodness_of_fit",
    "LinearFit": "curve_fits",
    "fit_linear": "curve_fits",
    "FourierFit": "curve_fits",
    "count_extrema": "curve_fits",
    "fit_fourier": "curve_fits",
    "resolvable_order": "curve_fits",
    "MarkerKinematics": "fitting",
    "fit_marker_kinematics": "fitting",
    "VERSION_NAMES": "rigid_body",
    "ANGULAR_METHODS": "rigid_body",
    "AngularKinematics": "rigid_body",
    "unobservable_axis": "rigid_body",
    "weak_axis_gain": "rigid_body",
    "omega_versions": "rigid_body",
    "alpha_versions": "rigid_body",
    "omega_least_squares": "rigid_body",
    "alpha_least_squares": "rigid_body",
    "plane_normal": "rigid_body",
    "singularity_index": "rigid_body",
    "angular_kinematics": "rigid_body",
    "PointKinematics": "saddle_point",
    "body_frame": "saddle_point",
    "saddle_body_coordinates": "saddle_point",
    "saddle_point_kinematics": "saddle_point",
}

__all__ = [
    # smoothing
    "span_points",
    "rloess",
    "bridge_gaps",
    "regularize_depth",
    # period
    "estimate_period",
    "analysis_window",
    # frames
    "CAMERA_DOWN",
    "MotionFrame",
    "plumb_gravity",
    "travel_velocity",
    "motion_frame",
    "to_motion_frame",
    "vectors_to_motion_frame",
    # registration
    "Registration",
    "layout_ratio",
    "check_marker_layout",
    "marker_model",
    "register_rigid",
    "broken_distance_samples",
    # goodness of fit, curve fits and the fits of every marker
    "CRITERIA",
    "GoodnessOfFit",
    "LinearFit",
    "fit_linear",
    "FourierFit",
    "count_extrema",
    "fit_fourier",
    "resolvable_order",
    "MarkerKinematics",
    "fit_marker_kinematics",
    # rigid body
    "VERSION_NAMES",
    "ANGULAR_METHODS",
    "AngularKinematics",
    "unobservable_axis",
    "weak_axis_gain",
    "omega_versions",
    "alpha_versions",
    "omega_least_squares",
    "alpha_least_squares",
    "plane_normal",
    "singularity_index",
    "angular_kinematics",
    # saddle point
    "PointKinematics",
    "body_frame",
    "saddle_body_coordinates",
    "saddle_point_kinematics",
]


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
