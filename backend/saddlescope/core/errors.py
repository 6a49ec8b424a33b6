"""Typed errors of the scientific core.

Each carries a human-readable message naming what was wrong (clip, camera, marker) so the CLI,
the API and failed jobs can show it as it is, without a traceback.
"""

__all__ = [
    "SaddleScopeError",
    "InputError",
    "VideoError",
    "CalibrationError",
    "CamerasMovedError",
    "SyncError",
    "DetectionError",
    "TriangulationError",
    "KinematicsError",
    "VibrationError",
    "BundleError",
    "MocapFileError",
]


class SaddleScopeError(Exception):
    """Base of every error a user can cause with bad input."""


class InputError(SaddleScopeError, ValueError):
    """An argument or file has the wrong shape, type or content."""


class VideoError(SaddleScopeError):
    """A clip cannot be read: missing, unreadable, truncated, wrong fps or size."""


class CalibrationError(SaddleScopeError):
    """No board found, too few board views, or a calibration that fails its checks."""


class CamerasMovedError(CalibrationError):
    """A ride's markers no longer fit its rig's calibration: the cameras moved since the rig was calibrated."""


class SyncError(SaddleScopeError):
    """No flash found, clips too short, or clips of different frame rates."""


class DetectionError(SaddleScopeError):
    """Markers cannot be found or told apart."""


class TriangulationError(SaddleScopeError):
    """Too few views, degenerate geometry."""


class KinematicsError(SaddleScopeError):
    """Too short a ride, markers lost for most of it, degenerate marker layout, no static shot."""


class VibrationError(SaddleScopeError, ValueError):
    """Unknown weighting, bad sampling rate or duration."""


class BundleError(SaddleScopeError):
    """A ride bundle is missing files, has an unknown camera role, gait or format."""


class MocapFileError(SaddleScopeError):
    """A C3D or TRC file is empty, truncated or malformed."""
