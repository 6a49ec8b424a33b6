"""Motion similarity of marker trajectories (SCIENCE.md stage 13, seed 004).

The dissertation models each marker's trajectory as a 3-D discrete curve on a cubic grid and
writes it as Bribiesca's chain code of *orthogonal direction changes*; two motions are then
compared as strings, by Needleman-Wunsch global alignment and by the shape dissimilarity of
Bribiesca & Aguilar, and, for reference, by dynamic time warping (DTW) of the raw samples.

- :mod:`.chain_code`: the grid walk of a trajectory (the dissertation's anchored walk, or
  nearest-vertex snapping) and its chain code;
- :mod:`.canonical`: canonical frames (motion frame and stride phase; Kabsch) and the grid step
  chosen from the measured noise;
- :mod:`.measures`: chain-code measures of two curves in one canonical frame;
- :mod:`.alignment`: Needleman-Wunsch alignment and its similarity;
- :mod:`.shape`: maximal common sub-chains and the shape dissimilarity D';
- :mod:`.recordings`: two recordings aligned in time (cycle phase or subsequence DTW) and space;
- :mod:`.dtw`: dynamic time warping (the plain numpy reference);
- :mod:`.stride_ranking`: two rides' mean strides compared (DTW over cyclic shifts, chain codes) and
  ride pairs ranked;
- :mod:`.trajectories`: all of them per marker subset and time window.

The dissertation's own implementation took 41 minutes for one pair of sensors; everything here is
vectorised numpy and takes well under a second for chains of 10,000 elements.
"""

from saddlescope.core.similarity.alignment import (
    DISSERTATION_NW_SCORES,
    GAP,
    alignment_similarity,
    default_band,
    needleman_wunsch,
    nw_similarity,
)
from saddlescope.core.similarity.canonical import (
    DEFAULT_HARMONICS,
    DEFAULT_STRIDE_SAMPLES,
    NOISE_STEPS,
    RideStrides,
    align_phase,
    fourier_shift,
    kabsch_align,
    noise_of_track,
    noise_step,
    ride_strides,
    time_normalise,
)
from saddlescope.core.similarity.chain_code import (
    CODE_BACK,
    CODE_CROSS,
    CODE_NEG_BACK,
    CODE_NEG_CROSS,
    CODE_REVERSAL,
    CODE_STILL,
    CODE_STRAIGHT,
    DEFAULT_CELLS,
    WALKS,
    accumulated_directions,
    chain_code_3d,
    chain_to_path,
    codes_from_steps,
    default_step,
    grid_walk,
)
from saddlescope.core.similarity.dtw import dtw_distance_reference
from saddlescope.core.similarity.measures import chain_measures, closed_loop_chain
from saddlescope.core.similarity.recordings import (
    ALIGNMENTS,
    AlignedRecordings,
    RecordingSignature,
    align_recordings,
    align_signatures,
    recording_signature,
    remove_progression,
    stretch_differences,
)
from saddlescope.core.similarity.shape import maximal_matches, shape_dissimilarity
from saddlescope.core.similarity.stride_ranking import (
    METHODS,
    dtw_distance,
    most_similar_rides,
    normalise_stride,
    stride_distance_dtw,
    stride_similarity_chaincode,
)
from saddlescope.core.similarity.trajectories import trajectory_similarity

__all__ = [
    # chain code
    "CODE_STRAIGHT",
    "CODE_CROSS",
    "CODE_BACK",
    "CODE_NEG_CROSS",
    "CODE_NEG_BACK",
    "CODE_REVERSAL",
    "CODE_STILL",
    "DEFAULT_CELLS",
    "WALKS",
    "default_step",
    "grid_walk",
    "codes_from_steps",
    "chain_code_3d",
    "accumulated_directions",
    "chain_to_path",
    # alignment
    "GAP",
    "DISSERTATION_NW_SCORES",
    "default_band",
    "needleman_wunsch",
    "alignment_similarity",
    "nw_similarity",
    # shape
    "maximal_matches",
    "shape_dissimilarity",
    # canonical frames and the noise-based step
    "DEFAULT_STRIDE_SAMPLES",
    "DEFAULT_HARMONICS",
    "NOISE_STEPS",
    "RideStrides",
    "ride_strides",
    "align_phase",
    "fourier_shift",
    "time_normalise",
    "kabsch_align",
    "noise_of_track",
    "noise_step",
    # measures of canonical curves
    "closed_loop_chain",
    "chain_measures",
    # recordings aligned in time and space
    "ALIGNMENTS",
    "AlignedRecordings",
    "RecordingSignature",
    "align_recordings",
    "align_signatures",
    "recording_signature",
    "remove_progression",
    "stretch_differences",
    # dynamic time warping
    "dtw_distance_reference",
    # per marker subset and time window
    "trajectory_similarity",
    # mean strides compared and ride pairs ranked
    "METHODS",
    "dtw_distance",
    "most_similar_rides",
    "normalise_stride",
    "stride_distance_dtw",
    "stride_similarity_chaincode",
]
