"""SaddleScope: saddle kinematics and rider whole-body vibration from three ordinary cameras."""

__version__ = "0.1.0"
