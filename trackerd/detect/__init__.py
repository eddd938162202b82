"""Finding the pointer's red and blue ends in camera frames (report section 3.2)."""

from trackerd.detect.detector import ColourEndDetector, detect_all_cameras, detect_ends
from trackerd.detect.result import EndDetection, ImageDetections

__all__ = ["ColourEndDetector", "EndDetection", "ImageDetections", "detect_all_cameras", "detect_ends"]
