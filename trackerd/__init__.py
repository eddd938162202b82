"""trackerd: real-time tracking of a two-colour pointer aimed at a display wall.

The method is the one of AFRL-RI-RS-TR-2007-280 ("Gesture Recognition Development
for the Interactive DataWall"): find the red and the blue end of a passive pointer
in two calibrated camera images, triangulate both ends in 3D, extend the pointer's
line to the wall plane and report where on the wall it points.
"""

__version__ = "0.1.0"
