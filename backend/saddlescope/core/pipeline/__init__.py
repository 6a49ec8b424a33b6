"""The whole analysis of a ride, stage by stage (thesis stages 1-12).

- :mod:`.inputs`: what the pipeline reads (:class:`ClipReader`) and reports (:class:`Progress`);
- :mod:`.setup`: the board, synchronisation and calibration (stages 1-2);
- :mod:`.detection`: the markers found and triangulated in every clip (stages 3-4);
- :mod:`.result`: the :class:`~saddlescope.core.types.RideResult` assembled;
- :mod:`.run`: :func:`analyze_ride`, which runs them in order.

The saddle point's kinematics and indicators (stages 5-12) live in :mod:`saddlescope.core.saddle`.
"""

from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.detection import RideTracks, depth_uncertainty, detect_ride
from saddlescope.core.pipeline.inputs import STAGE_WEIGHTS, ClipReader, Progress
from saddlescope.core.pipeline.result import assemble_result, fits_document
from saddlescope.core.pipeline.run import analyze_ride
from saddlescope.core.pipeline.setup import (
    board_coverage,
    calibrate_from_clips,
    frame_clocks,
    still_views,
    synchronise,
    synchronise_clips,
)

__all__ = ["STAGE_WEIGHTS", "ClipReader", "PipelineParams", "Progress", "RideTracks", "analyze_ride",
           "assemble_result", "board_coverage", "calibrate_from_clips", "depth_uncertainty",
           "detect_ride", "fits_document", "frame_clocks", "still_views", "synchronise",
           "synchronise_clips"]
