"""Pure geometry on NumPy arrays: cameras and rays, triangulation, the wall plane.

* camera.py        pixel <-> ray, projection (eq. 1-2, 14)
* rotation.py      pitch, yaw, roll (eq. 18-22)
* triangulation.py closest approach of two rays, N-camera least squares (eq. 15-17)
* wall.py          wall plane (eq. 23-25), line-plane intersection (eq. 26-28), wall frame
"""
