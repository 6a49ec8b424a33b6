"""The science: numpy, scipy and OpenCV only (checked by import-linter).

One package or module per stage (see docs/architecture.md): ``calibration``, ``sync``, ``detection``,
``triangulation``, ``kinematics``, ``saddle``, ``vibration``, ``similarity``, ``validation``, and
``pipeline``, which runs them on a ride. Import from the stage: nothing is re-exported here, so that
importing one stage does not load the others.
"""

__all__: list[str] = []
