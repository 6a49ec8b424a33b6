"""Motion-capture files: read C3D and TRC marker trajectories, write our own tracks as C3D or TRC.

``read_mocap`` returns a :class:`MocapData` whatever the format: labels, rate, points of shape
(F, M, 3) with NaN where a marker is missing, units ('mm' or 'm') and the first frame number.

- :mod:`.data`: :class:`MocapData` and what the readers and writers share;
- :mod:`.c3d`: C3D, read with the ``c3d`` package (what it repaired said as notes);
- :mod:`.trc`: the TRC text format;
- :mod:`.reader`: :func:`read_mocap`, the reader chosen by the file's extension.
"""

from saddlescope.io.mocap.c3d import read_c3d
from saddlescope.io.mocap.c3d_writer import write_c3d
from saddlescope.io.mocap.data import MocapData
from saddlescope.io.mocap.reader import read_mocap
from saddlescope.io.mocap.trc import read_trc, write_trc

__all__ = ["MocapData", "read_mocap", "read_c3d", "read_trc", "write_c3d", "write_trc"]
