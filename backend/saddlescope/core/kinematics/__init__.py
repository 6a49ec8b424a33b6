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
"""

from saddlescope.core.kinematics.curve_fits import FourierFit, LinearFit, count_extrema, fit_fourier, fit_linear
from saddlescope.core.kinematics.fitting import MarkerKinematics, fit_marker_kinematics
from saddlescope.core.kinematics.frames import (
    CAMERA_DOWN,
    MotionFrame,
    motion_frame,
    plumb_gravity,
    to_motion_frame,
    travel_velocity,
    vectors_to_motion_frame,
)
from saddlescope.core.kinematics.goodness_of_fit import CRITERIA, GoodnessOfFit
from saddlescope.core.kinematics.period import analysis_window, estimate_period
from saddlescope.core.kinematics.registration import (
    Registration,
    broken_distance_samples,
    check_marker_layout,
    layout_ratio,
    marker_model,
    register_rigid,
)
from saddlescope.core.kinematics.rigid_body import (
    ANGULAR_METHODS,
    VERSION_NAMES,
    AngularKinematics,
    alpha_least_squares,
    alpha_versions,
    angular_kinematics,
    omega_least_squares,
    omega_versions,
    plane_normal,
    singularity_index,
    unobservable_axis,
    weak_axis_gain,
)
from saddlescope.core.kinematics.saddle_point import (
    PointKinematics,
    body_frame,
    saddle_body_coordinates,
    saddle_point_kinematics,
)
from saddlescope.core.kinematics.smoothing import bridge_gaps, regularize_depth, rloess, span_points

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
