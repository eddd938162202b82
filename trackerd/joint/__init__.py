"""Which candidate is each ball in each camera: chosen jointly, by what the geometry allows.

Per image, a red blob on a slide and the red ball can look alike; across
cameras they cannot. Among every camera's candidates of both colours
(:mod:`trackerd.detect.search`), the choice is the combination that

* triangulates: each ball's rays from two or more cameras meet (their gap),
* has the ball's size at that distance in every camera that sees it (a ball of
  radius R at distance d images with a radius of about f R / d),
* is one pointer: the red and the blue point are the pointer's length apart,
* lies in the room, in front of the wall, and in front of every camera,

scored by how far each of those is from exact, in units of what measurement
noise allows. Cameras beyond the first two join a choice when one of their
candidates lies where the choice projects. The answer says, per camera and
colour, which candidate (or none), so the pointer fit
(:mod:`trackerd.geometry.pointer_fit`) can use cameras that see only one end.

Layout: :mod:`trackerd.joint.points` triangulates each colour's candidates and pairs the points,
:mod:`trackerd.joint.looks` looks for a ball where no camera offered it, :mod:`trackerd.joint.lone` places a
ball that one camera alone offers, :mod:`trackerd.joint.choice` runs the stages.
"""

from trackerd.joint.choice import choose_jointly
from trackerd.joint.lone import LONE_MIN_COS, length_fixes_depth
from trackerd.joint.looks import GUIDED_POINTS, Look, RodFrom
from trackerd.joint.points import JointChoice

__all__ = ["GUIDED_POINTS", "LONE_MIN_COS", "JointChoice", "Look", "RodFrom", "choose_jointly", "length_fixes_depth"]
