"""Camera acquisition: frames from two (or more) cameras, paired into synchronized sets.

The pipeline sees only :class:`PairSource`; :class:`~trackerd.acquisition.live.LivePairSource`
(live cameras through Aravis or pylon) is imported from its module so that this
package needs neither PyGObject nor pypylon.
"""

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.acquisition.source import PairSource
from trackerd.acquisition.status import CameraStatus, SourceStatus

__all__ = ["CameraStatus", "Frame", "FramePair", "PairSource", "SourceStatus"]
