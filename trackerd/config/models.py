"""The rig configuration: pydantic models for everything one TOML file describes.

A *rig* is the cameras, the wall, the pointer, the detector's thresholds and the
outputs of one installation. Calibration (each camera's intrinsics and
extrinsics, and optionally the wall) may live in a separate file that the rig
file names; see :mod:`trackerd.config.loader` for how the two are merged.

Every model forbids unknown keys, so a misspelt key is an error that names the
keys that are allowed rather than a setting silently ignored. Units are in the
field names: ``_m`` metres, ``_mm`` millimetres, ``_px`` pixels, ``_deg``
degrees, ``_us`` microseconds, ``_ms`` milliseconds, ``_hz`` hertz.

World frame used throughout (docs/geometry.md): right-handed, metres. The
example rigs put the origin at the wall's bottom-left corner with x along the
wall to the right, y up and z out of the wall into the room; any other frame
works as long as cameras and wall are given in the same one.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from trackerd.config.acquisition import CameraAcquisition, RigAcquisition
from trackerd.config.base import ConfigModel
from trackerd.config.interaction import InteractionConfig
from trackerd.config.console import ConsoleConfig
from trackerd.config.recording import RecordingConfig

Vec3 = tuple[float, float, float]

COLOUR_PIXEL_FORMATS = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8")
MONO_PIXEL_FORMATS = ("Mono8", "Mono10", "Mono12", "Mono16")
CALIBRATION_ONLY_FORMAT = "Mono8"
"""A monochrome format a camera may have in a rig used only to calibrate: tracking needs colour."""
CameraBackend = Literal["aravis", "pylon", "gentl"]
"""The acquisition backends a camera can be reached through (docs/acquisition.md)."""
FeatureValue = bool | int | float | str
PixelFormat = Literal["BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8"]

# OpenCV accepts these distortion vector lengths (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]).
OPENCV_DISTORTION_LENGTHS = (0, 4, 5, 8, 12, 14)


_Model = ConfigModel


# --------------------------------------------------------------------------- intrinsics


class FovIntrinsics(_Model):
    """The report's simple camera model (section 3.4, eq. 14).

    A distortion-free pinhole with its principal point at the image centre, fixed
    by the horizontal field of view: a pixel spans ``f * tan(hfov / 2) / (width / 2)``
    on an image plane at focal length ``f`` (eq. 14), which is a focal length of
    ``(width / 2) / tan(hfov / 2)`` in pixels.
    """

    model: Literal["fov"]
    """Selects this model."""
    horizontal_fov_deg: float = Field(gt=0.0, lt=180.0)
    """Full horizontal angle of view, in degrees."""
    vertical_fov_deg: float | None = Field(default=None, gt=0.0, lt=180.0)
    """Full vertical angle of view; omit for square pixels (then it follows from the aspect ratio)."""
    focal_length_mm: float | None = Field(default=None, gt=0.0)
    """Lens focal length. Does not change any ray (eq. 14 scales out); reported for reference."""


class OpenCVIntrinsics(_Model):
    """A full pinhole model with OpenCV's lens distortion, as `cv2.calibrateCamera` returns it."""

    model: Literal["opencv"]
    """Selects this model."""
    fx_px: float = Field(gt=0.0)
    """Focal length along image x, in pixels."""
    fy_px: float = Field(gt=0.0)
    """Focal length along image y, in pixels."""
    cx_px: float
    """Principal point x, in pixels, measured from the left edge of the first pixel's centre (OpenCV)."""
    cy_px: float
    """Principal point y, in pixels, from the top."""
    distortion: tuple[float, ...] = ()
    """Distortion coefficients in OpenCV order: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]."""

    @field_validator("distortion")
    @classmethod
    def _distortion_length(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        if len(value) not in OPENCV_DISTORTION_LENGTHS:
            raise ValueError(
                f"has {len(value)} coefficients; OpenCV takes "
                + ", ".join(str(n) for n in OPENCV_DISTORTION_LENGTHS)
            )
        return value


Intrinsics = Annotated[FovIntrinsics | OpenCVIntrinsics, Field(discriminator="model")]


# --------------------------------------------------------------------------- extrinsics


class PoseExtrinsics(_Model):
    """Where the camera is and where it looks, as a camera operator would measure it.

    The angles follow the report's pitch, yaw and roll about the camera's x, y and
    z axes (eq. 18-20), composed as a pan-tilt head moves: yaw first, then pitch,
    then roll (eq. 21, docs/geometry.md). With all three at zero the camera is
    level and looks straight at the wall, along the world's -z axis.
    """

    kind: Literal["pose"]
    """Selects this form."""
    position_m: Vec3
    """The camera's optical centre in world coordinates."""
    yaw_deg: float = 0.0
    """Pan: positive turns the camera to its right."""
    pitch_deg: float = 0.0
    """Tilt: positive tilts the camera up."""
    roll_deg: float = 0.0
    """Rotation about the optical axis: positive turns the image content anticlockwise
    (the camera itself turns clockwise, seen from behind)."""


class OpenCVExtrinsics(_Model):
    """World-to-camera transform in OpenCV's convention: ``x_cam = R @ x_world + t``.

    This is what `cv2.solvePnP` and `cv2.stereoCalibrate` produce. Give the rotation
    either as a Rodrigues vector or as a matrix, not both.
    """

    kind: Literal["opencv"]
    """Selects this form."""
    rvec: Vec3 | None = None
    """Rotation as a Rodrigues vector (axis times angle in radians)."""
    rotation_matrix: tuple[Vec3, Vec3, Vec3] | None = None
    """Rotation as a 3x3 matrix, rows first."""
    tvec_m: Vec3
    """Translation t, in metres."""

    @model_validator(mode="after")
    def _one_rotation(self) -> OpenCVExtrinsics:
        if (self.rvec is None) == (self.rotation_matrix is None):
            raise ValueError("give exactly one of rvec or rotation_matrix")
        if self.rotation_matrix is not None:
            import numpy as np

            matrix = np.asarray(self.rotation_matrix, dtype=float)
            if not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-6) or np.linalg.det(matrix) < 0:
                raise ValueError("rotation_matrix is not a rotation (orthonormal, determinant +1)")
        return self


Extrinsics = Annotated[PoseExtrinsics | OpenCVExtrinsics, Field(discriminator="kind")]


# --------------------------------------------------------------------------- cameras


class CameraConfig(_Model):
    """One camera of the rig: how to find it, what it delivers, and (optionally) its calibration."""

    id: str = Field(pattern=r"^[A-Za-z0-9_-]{1,32}$")
    """Short name used in logs, messages and the calibration file, for example ``left``."""
    serial: str | None = None
    """Serial number, the usual way to find a GigE Vision camera."""
    address: str | None = None
    """IP address of the camera, an alternative to the serial number."""
    device_id: str | None = None
    """Device id as `trackerd cameras` lists it (Aravis's device id, or pylon's full name with
    ``backend = "pylon"``, the producer's device id with ``backend = "gentl"``), an alternative to
    serial and address."""
    width_px: int = Field(gt=0)
    """Image width delivered by the camera."""
    height_px: int = Field(gt=0)
    """Image height delivered by the camera."""
    pixel_format: str
    """GenICam pixel format: BayerRG8, BayerGB8, BayerGR8, BayerBG8, RGB8 or BGR8; Mono8 in a rig used
    only to calibrate (`trackerd calibrate` takes it, every tracking command refuses it)."""
    intrinsics: Intrinsics | None = None
    """Lens model; may instead come from the calibration file."""
    extrinsics: Extrinsics | None = None
    """Camera pose; may instead come from the calibration file."""
    acquisition: CameraAcquisition = CameraAcquisition()
    """How this camera is driven: exposure, gain, region, GigE transport (docs/acquisition.md)."""
    backend: CameraBackend = "aravis"
    """How the camera is reached: ``aravis`` (GigE Vision and USB3 Vision through Aravis) or
    ``pylon`` (Basler pylon through pypylon, the ``trackerd[gentl]`` extra: pylon's camera emulation,
    Basler GigE and USB cameras, and CoaXPress frame grabbers whose GenTL producer pylon loads) or
    ``gentl`` (any vendor's GenTL producer, named by ``producer``, through harvesters, the same extra:
    CameraLink and CoaXPress frame grabbers; docs/acquisition.md). A rig may mix them."""
    producer: str | None = None
    """Path of the GenTL producer (the frame grabber vendor's ``.cti`` file) that reaches the camera;
    ``gentl`` backend only, and required there. Absolute, or relative to the working directory; ``~``
    is expanded. Cameras naming the same file share one loaded producer."""
    features: dict[str, FeatureValue] = Field(default_factory=dict)
    """GenICam features written to the camera, in the order given, when it is opened (before the
    rig's own settings), for what the rig file has no key for: a frame grabber's link or tap
    configuration, or pylon's emulated camera's ``ImageFilename``. ``pylon`` and ``gentl`` backends only."""

    @field_validator("pixel_format")
    @classmethod
    def _colour_format(cls, value: str) -> str:
        # Mono8 is accepted here for a rig used to calibrate (a board is black and white);
        # load_rig, which every tracking command uses, refuses it with the reason.
        if value in MONO_PIXEL_FORMATS and value != CALIBRATION_ONLY_FORMAT:
            raise ValueError(
                f"{value} is monochrome and cannot tell the pointer's red end from its blue end;"
                f" use one of {', '.join(COLOUR_PIXEL_FORMATS)} ({CALIBRATION_ONLY_FORMAT} for calibration only)"
            )
        if value not in (*COLOUR_PIXEL_FORMATS, CALIBRATION_ONLY_FORMAT):
            raise ValueError(
                f"'{value}' is not supported; use one of {', '.join(COLOUR_PIXEL_FORMATS)}"
                f" ({CALIBRATION_ONLY_FORMAT} for calibration only)"
            )
        return value

    @model_validator(mode="after")
    def _backend_lookup(self) -> CameraConfig:
        if self.backend != "aravis" and self.address is not None:
            raise ValueError(
                f"address is for GigE Vision cameras reached through Aravis; a camera with backend ="
                f" '{self.backend}' is found by serial or device_id (as `trackerd cameras` lists it)"
            )
        if self.backend == "aravis" and self.features:
            raise ValueError("features are written by the pylon and gentl backends only (backend = 'pylon' or 'gentl')")
        if self.backend == "gentl" and not self.producer:
            raise ValueError(
                "backend = 'gentl' needs producer = the path of the GenTL producer (.cti file) that reaches"
                " the camera"
            )
        if self.backend != "gentl" and self.producer is not None:
            raise ValueError(f"producer is for backend = 'gentl' (this camera's backend is '{self.backend}')")
        return self

    @model_validator(mode="after")
    def _principal_point_inside(self) -> CameraConfig:
        intr = self.intrinsics
        if isinstance(intr, OpenCVIntrinsics) and not (
            0 <= intr.cx_px < self.width_px and 0 <= intr.cy_px < self.height_px
        ):
            raise ValueError(
                f"principal point ({intr.cx_px}, {intr.cy_px}) lies outside the"
                f" {self.width_px}x{self.height_px} image"
            )
        return self


# --------------------------------------------------------------------------- wall


class WallConfig(_Model):
    """The display wall: its plane (eq. 23-25) and its 2D frame (origin, x along, y up).

    Either give the four corners of the display area (then everything follows), or
    give three or more points on the plane together with the frame: ``origin_m``,
    ``x_direction``, ``y_direction``, ``width_m`` and ``height_m``.
    """

    corners_m: tuple[Vec3, Vec3, Vec3, Vec3] | None = None
    """Display corners in world coordinates: bottom-left, bottom-right, top-right, top-left."""
    points_m: tuple[Vec3, ...] | None = None
    """Three or more measured points on the wall plane (a least-squares plane when more than three)."""
    origin_m: Vec3 | None = None
    """With points_m: the display's bottom-left corner (projected onto the plane)."""
    x_direction: Vec3 | None = None
    """With points_m: a direction along the bottom edge, to the right (projected onto the plane)."""
    y_direction: Vec3 | None = None
    """With points_m: a direction roughly up the wall (made perpendicular to x in the plane)."""
    width_m: float | None = Field(default=None, gt=0.0)
    """With points_m: width of the display area along x."""
    height_m: float | None = Field(default=None, gt=0.0)
    """With points_m: height of the display area along y."""
    display_width_px: int | None = Field(default=None, gt=0)
    """Width of the displayed image in pixels, to report hits in display pixels."""
    display_height_px: int | None = Field(default=None, gt=0)
    """Height of the displayed image in pixels."""
    planarity_tolerance_m: float = Field(default=0.01, gt=0.0)
    """Corners or points further than this from their best-fit plane are rejected as a mistake."""

    @model_validator(mode="after")
    def _one_description(self) -> WallConfig:
        frame_keys = ("origin_m", "x_direction", "y_direction", "width_m", "height_m")
        if self.corners_m is not None:
            given = [k for k in (*frame_keys, "points_m") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"corners_m already fixes the wall; remove {', '.join(given)}")
        elif self.points_m is not None:
            if len(self.points_m) < 3:
                raise ValueError("points_m needs three or more points (eq. 24)")
            missing = [k for k in frame_keys if getattr(self, k) is None]
            if missing:
                raise ValueError(f"with points_m also give {', '.join(missing)}")
        else:
            raise ValueError("give either corners_m or points_m (with origin_m, x_direction, ...)")
        if (self.display_width_px is None) != (self.display_height_px is None):
            raise ValueError("give both display_width_px and display_height_px, or neither")
        return self


# --------------------------------------------------------------------------- pointer


class PointerConfig(_Model):
    """The passive pointer: a rod with a coloured ball at each end."""

    front_colour: Literal["red", "blue"] = "red"
    """The end nearer the wall when pointing: the pointing direction runs from the other end to this one."""
    length_m: float = Field(gt=0.0)
    """Distance between the centres of the two coloured ends."""
    length_tolerance_m: float = Field(default=0.05, gt=0.0)
    """A triangulated pointer whose length differs from length_m by more is rejected as impossible."""
    end_diameter_m: float = Field(gt=0.0)
    """Diameter of each coloured ball."""
    rod_diameter_m: float = Field(default=0.012, gt=0.0)
    """Diameter of the (dark) rod joining the balls; used by the simulator and the bias model."""

    @model_validator(mode="after")
    def _geometry(self) -> PointerConfig:
        if self.end_diameter_m >= self.length_m:
            raise ValueError("end_diameter_m must be smaller than length_m")
        if self.rod_diameter_m > self.end_diameter_m:
            raise ValueError("rod_diameter_m must not exceed end_diameter_m")
        return self


# --------------------------------------------------------------------------- detector


class ColourThreshold(_Model):
    """When a pixel counts as one end's colour (report eq. 10-11, made robust to white and grey)."""

    min_excess: int = Field(default=40, ge=1, le=255)
    """The colour's channel must exceed the larger of the other two channels by at least this much."""
    min_value: int = Field(default=60, ge=0, le=255)
    """And the colour's channel itself must be at least this bright."""


class DetectorConfig(_Model):
    """Thresholds of the colour-end detector (trackerd/detect)."""

    red: ColourThreshold = ColourThreshold(min_excess=70)
    """Threshold for the red end. Skin reaches an excess of about 55 and muted reds on a
    projected slide about 50: the default keeps both out (docs/detection.md, tuning)."""
    blue: ColourThreshold = ColourThreshold(min_excess=60, min_value=60)
    """Threshold for the blue end."""
    min_area_px: float = Field(default=12.0, gt=0.0)
    """Smallest blob, in full-resolution pixels, accepted as an end."""
    max_area_px: float = Field(default=20000.0, gt=0.0)
    """Largest blob accepted as an end."""
    max_elongation: float = Field(default=3.0, ge=1.0)
    """A ball images as a near-circle; blobs longer than this times their width are rejected."""
    min_fill: float = Field(default=0.45, gt=0.0, le=1.0)
    """Blob area over its bounding-box area; a disc fills about 0.79, thin streaks much less."""
    search_step_px: int = Field(default=8, ge=2, le=64)
    """Spacing of the subsampled full-frame pass; an end smaller than about 1.5 times this across
    may be missed by a full search (a tracked end is followed smaller)."""
    track_window_px: int = Field(default=96, ge=8)
    """Half-size of the window searched first around the previous frame's position."""
    centroid: Literal["coverage", "weighted", "bbox"] = "coverage"
    """How an end's centre is measured. coverage: the centroid of every pixel's estimated coverage by
    the ball (on Bayer frames each pixel's own channel is used, so the rim is resolved at full
    resolution; the most accurate); weighted: coverage-weighted centroid of the end's own colour
    samples only (cheaper, about twice the error across the pointer on Bayer frames); bbox: the
    report's bounding-box midpoint (eq. 12)."""

    @model_validator(mode="after")
    def _area_range(self) -> DetectorConfig:
        if self.min_area_px >= self.max_area_px:
            raise ValueError("min_area_px must be smaller than max_area_px")
        return self


MIN_LEARNED_EXCESS = 10
"""The lowest threshold `trackerd calibrate pointer` learns (sensor noise reaches it on grey)."""


class LearnedColour(_Model):
    """One end's colour as `trackerd calibrate pointer` measured it in this room (docs/calibration.md).

    Excesses are in grey levels of the detector's test (the colour's channel minus the larger of
    the other two; trackerd/detect/margin.py)."""

    min_excess: int = Field(ge=1, le=255)
    """The threshold learned for this end (replaces ``[detector.<colour>] min_excess`` unless the rig
    file gives that table)."""
    min_value: int = Field(ge=0, le=255)
    """The brightness threshold learned for this end."""
    ball_excess: int = Field(ge=-255, le=255)
    """What the end's paint reached: the 10th percentile of its core samples, over every camera and frame
    (the lowest camera's)."""
    background_excess: int = Field(ge=-255, le=255)
    """The highest excess anything else in view reached over a block of 2 x 2 samples (the highest
    camera's, in any frame). The daemon warns when what it sees comes closer to ``ball_excess``."""

    @model_validator(mode="after")
    def _finds_the_ball(self) -> LearnedColour:
        if self.min_excess > max(self.ball_excess, MIN_LEARNED_EXCESS):
            raise ValueError(
                f"min_excess {self.min_excess} is above the ball's own excess ({self.ball_excess}): this end"
                " would never pass the colour test"
            )
        return self

    @property
    def margin(self) -> int:
        """Ball over background, grey levels: above 0, a threshold between them finds only the ball."""
        return self.ball_excess - self.background_excess


class PointerColours(_Model):
    """The pointer's colours learned in this room by `trackerd calibrate pointer`.

    Written into the calibration file; the detector's red and blue thresholds come from it unless
    the rig file sets ``[detector.red]`` or ``[detector.blue]``, which stay overrides."""

    learned: str
    """When they were learned (ISO 8601 local time)."""
    frames: int = Field(ge=1)
    """Frame pairs the figures come from."""
    red: LearnedColour
    """The red end."""
    blue: LearnedColour
    """The blue end."""

    def of(self, colour: str) -> LearnedColour:
        return self.red if colour == "red" else self.blue


# --------------------------------------------------------------------------- locator


class LocatorConfig(_Model):
    """How detections become a pointer line and a wall hit (trackerd/locator.py)."""

    max_ray_gap_m: float = Field(default=0.03, gt=0.0)
    """Reject a fix when an end's rays miss its estimated centre by more than this
    (a wrong blob in one camera gives rays that do not meet)."""
    min_plane_angle_deg: float = Field(default=4.6, gt=0.0, lt=90.0)
    """Below this angle between the cameras' interpretation planes the pointer's line is
    taken through the two triangulated ends instead (docs/geometry.md)."""
    sphere_correction: bool = True
    """Correct each ball's image centroid for perspective (an imaged sphere's centre is not the
    projection of its centre) before estimating the line."""
    centroid_sigma_px: float = Field(default=0.05, gt=0.0)
    """Assumed standard deviation of a centroid across the pointer, used for the hit's uncertainty."""
    refine: Literal["auto", "always", "never"] = "auto"
    """When each end's outline is fitted and the pointer fitted to every camera at once
    (docs/geometry.md, "The pointer fit"): ``auto`` on every first sighting, whenever the detector's ends
    do not make a pointer or make a loose one (rays that miss by millimetres, a length off by a
    centimetre), and while the detector's centroids disagree with the balls' outlines (an end partly
    hidden, dim, merged with a picture); ``always`` on every pair;
    ``never`` only the interpretation planes on the detector's centroids (the code before the fit)."""
    search_every_pairs: int = Field(default=6, ge=1, le=600)
    """While the pointer is not found, the search over every camera's candidates (tens of milliseconds,
    where a tracked pair takes one or two) runs on every this many-th pair, so a room without the pointer
    does not keep a core busy; a first sighting after a reset is searched at once."""
    length_sigma_m: float = Field(default=0.003, gt=0.0)
    """How exactly the pointer's length (pointer.length_m) is known: the pointer fit holds the two
    ends this far apart, within this standard deviation."""


# --------------------------------------------------------------------------- outputs


class ZmqOutput(_Model):
    """ZeroMQ publishing of hits, pointer poses and status (docs/protocol.md).

    Binding anything but a loopback address (127.0.0.0/8, ::1, ``localhost``) or an
    ``ipc://`` path needs CURVE (``curve_secret_key_file``) or an explicit
    ``allow_insecure_network = true``: the messages say where a presenter points,
    and without CURVE anyone on the network could read them.
    """

    endpoints: tuple[str, ...] = Field(default=("tcp://127.0.0.1:5560",), min_length=1)
    """Endpoints the PUB socket binds: ``tcp://HOST:PORT`` (HOST an address, ``localhost``,
    an interface name or ``*``; PORT may be ``*`` for any free port) or ``ipc:///path``."""
    send_hwm_messages: int = Field(default=1000, ge=1, le=1_000_000)
    """Messages queued per subscriber before further messages to that subscriber are dropped
    (ZeroMQ SNDHWM): a slow or stalled subscriber never blocks or slows the pipeline."""
    linger_ms: int = Field(default=200, ge=0, le=10_000)
    """On shutdown, how long queued messages may still be sent before the socket is dropped."""
    status_interval_ms: float = Field(default=1000.0, gt=0.0, le=60_000.0)
    """Period of the ``status`` message; it is also sent on every change of state."""
    curve_secret_key_file: Path | None = None
    """The daemon's CURVE key pair (a ``.key_secret`` file from ``trackerd keys server``).
    Setting it turns on CURVE encryption and authentication for every endpoint. A relative
    path is relative to the rig file."""
    curve_authorized_keys_dir: Path | None = None
    """A directory of client public keys (``*.key`` files from ``trackerd keys client``);
    only those clients may subscribe. Omit to accept any client that knows the server's
    public key. Needs curve_secret_key_file. A relative path is relative to the rig file."""
    allow_insecure_network: bool = False
    """Bind non-loopback addresses without CURVE: anyone who can reach the port reads every
    message. For isolated networks only."""

    @field_validator("endpoints")
    @classmethod
    def _endpoint_syntax(cls, endpoints: tuple[str, ...]) -> tuple[str, ...]:
        for endpoint in endpoints:
            cls.endpoint_host(endpoint)
        if len(set(endpoints)) != len(endpoints):
            raise ValueError("lists the same endpoint twice")
        return endpoints

    @model_validator(mode="after")
    def _secure_network(self) -> ZmqOutput:
        if self.curve_authorized_keys_dir is not None and self.curve_secret_key_file is None:
            raise ValueError("curve_authorized_keys_dir needs curve_secret_key_file (CURVE is off without it)")
        exposed = self.insecure_endpoints()
        if exposed:
            raise ValueError(
                f"{', '.join(exposed)} is reachable from the network; set curve_secret_key_file"
                " (make one with `trackerd keys server`) or allow_insecure_network = true"
            )
        return self

    @staticmethod
    def endpoint_host(endpoint: str) -> str | None:
        """The host part of a ``tcp://`` endpoint (None for ``ipc://``); ValueError when malformed."""
        scheme, sep, rest = endpoint.partition("://")
        if not sep or scheme not in ("tcp", "ipc"):
            raise ValueError(f"'{endpoint}' is not a tcp://HOST:PORT or ipc:///path endpoint")
        if scheme == "ipc":
            if not rest:
                raise ValueError(f"'{endpoint}' names no path")
            return None
        host, colon, port = rest.rpartition(":")
        if not colon or not host:
            raise ValueError(f"'{endpoint}' needs HOST:PORT, for example tcp://127.0.0.1:5560")
        if port != "*" and not (port.isdigit() and 1 <= int(port) <= 65535):
            raise ValueError(f"'{endpoint}': port '{port}' is not a number from 1 to 65535 or '*'")
        if host.startswith("[") and host.endswith("]"):
            host = host[1:-1]
        return host

    @staticmethod
    def is_loopback_host(host: str) -> bool:
        """Whether a tcp endpoint's host is reachable from this machine only."""
        import ipaddress

        if host in ("localhost", "lo"):
            return True
        try:
            return ipaddress.ip_address(host).is_loopback
        except ValueError:
            return False  # '*', an interface name or a host name: assume the network

    def insecure_endpoints(self) -> list[str]:
        """Endpoints reachable from the network that would carry plain text (empty when allowed)."""
        if self.curve_secret_key_file is not None or self.allow_insecure_network:
            return []
        return [
            e for e in self.endpoints
            if (host := self.endpoint_host(e)) is not None and not self.is_loopback_host(host)
        ]


class OutputsConfig(_Model):
    """Where results go."""

    zmq: ZmqOutput = ZmqOutput()
    """ZeroMQ publisher (docs/protocol.md)."""


# --------------------------------------------------------------------------- simulation


class SimulationConfig(_Model):
    """How the scene simulator renders this rig (trackerd/sim). Ignored by live tracking."""

    seed: int = 7
    """Seed for the room's clutter, so renders are reproducible."""
    room_depth_m: float = Field(default=6.0, gt=0.0)
    """Distance from the wall to the back of the room."""
    room_margin_m: float = Field(default=1.5, ge=0.0)
    """How far the side walls extend beyond the display area on each side."""
    room_height_m: float = Field(default=3.0, gt=0.0)
    """Floor to ceiling."""
    display_height_above_floor_m: float = Field(default=0.9, ge=0.0)
    """Height of the display's bottom edge above the floor."""
    clutter: int = Field(default=12, ge=0)
    """Number of distractor objects (posters, stickers, strips, balls), a third red, a third blue."""
    hand: bool = True
    """Render a skin-coloured hand holding the pointer's handle (skin is a reddish distractor)."""
    presenter_distance_m: tuple[float, float] = (1.2, 2.8)
    """Range of distances of the pointer's tip from the wall for random poses."""
    hand_height_m: tuple[float, float] = (1.0, 1.8)
    """Range of heights of the pointer's tip above the floor for random poses."""
    noise_sigma: float = Field(default=1.0, ge=0.0)
    """Sensor read noise, standard deviation in 8-bit grey levels. The defaults model a 1080p
    CMOS machine-vision sensor (about 32 000 e- full well, 7 e- read noise) at +12 dB gain, as
    a 60 fps camera with a short exposure indoors needs; docs/simulation.md."""
    shot_noise: float = Field(default=0.2, ge=0.0)
    """Photon (shot) noise scale: the standard deviation in grey levels is this times
    sqrt(grey level) (0.2: 31 electrons per grey level)."""
    supersampling: int = Field(default=4, ge=1, le=8)
    """Anti-aliasing of the pointer: rays per pixel along each axis (4 means 16 rays per pixel)."""
    background_supersampling: int = Field(default=2, ge=1, le=4)
    """Anti-aliasing of the static room, rendered once per camera and cached."""


# --------------------------------------------------------------------------- rig


class RigConfig(_Model):
    """A whole installation: the top level of a rig TOML file."""

    version: Literal[1] = 1
    """Format version of the rig file."""
    name: str = "rig"
    """A label shown in logs and status messages."""
    calibration: Path | None = None
    """A calibration TOML file (relative to this file) that supplies intrinsics, extrinsics and
    optionally the wall; its values replace the ones given here."""
    cameras: tuple[CameraConfig, ...] = Field(min_length=2)
    """Two or more cameras; the first two are the stereo pair."""
    wall: WallConfig | None = None
    """The display wall (or from the calibration file). Tracking needs it; `trackerd calibrate
    intrinsics` and `stereo` do not, `calibrate wall` needs its nominal size."""
    pointer: PointerConfig | None = None
    """The pointer. Tracking, `calibrate wall` and `calibrate check` need it; intrinsics and stereo do
    not."""
    acquisition: RigAcquisition = RigAcquisition()
    """Trigger mode, frame pairing and camera-loss handling shared by all cameras."""
    detector: DetectorConfig = DetectorConfig()
    """Colour-end detector settings."""
    pointer_colours: PointerColours | None = None
    """The pointer's colours in this room, from the calibration file (where `trackerd calibrate pointer`
    writes them): the detector's thresholds for each end unless ``[detector.red]`` / ``[detector.blue]``
    is given here, and the figures the daemon's colour watch compares what it sees with."""
    locator: LocatorConfig = LocatorConfig()
    """Line estimation and quality gates."""
    outputs: OutputsConfig = OutputsConfig()
    """Output settings."""
    recording: RecordingConfig = RecordingConfig()
    """Recording from the running daemon (docs/recording.md)."""
    interaction: InteractionConfig = InteractionConfig()
    """Smoothing, pointing events, gestures and TUIO output (docs/protocol.md)."""
    console: ConsoleConfig = ConsoleConfig()
    """The operator's console: live camera views, wall map, status, metrics (docs/console.md)."""
    simulation: SimulationConfig = SimulationConfig()
    """Scene simulator settings (only used when rendering)."""

    @field_validator("cameras")
    @classmethod
    def _unique_ids(cls, cameras: tuple[CameraConfig, ...]) -> tuple[CameraConfig, ...]:
        ids = [c.id for c in cameras]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ValueError(f"camera ids must be unique; repeated: {', '.join(duplicates)}")
        return cameras

    def camera(self, camera_id: str) -> CameraConfig:
        """The camera with this id (KeyError naming the known ids otherwise)."""
        for cam in self.cameras:
            if cam.id == camera_id:
                return cam
        raise KeyError(f"no camera '{camera_id}'; the rig has {', '.join(c.id for c in self.cameras)}")


# --------------------------------------------------------------------------- calibration file


class CameraCalibration(_Model):
    """One camera's entry in a calibration file."""

    intrinsics: Intrinsics | None = None
    """Lens model, replacing the rig file's."""
    extrinsics: Extrinsics | None = None
    """Camera pose, replacing the rig file's."""
    info: dict[str, str | int | float] = {}
    """Provenance written by `trackerd calibrate`: date, board, number of views, RMS error."""


class CalibrationFile(_Model):
    """The top level of a calibration TOML file: ``[cameras.<id>]`` tables and an optional wall."""

    version: Literal[1] = 1
    """Format version of the calibration file."""
    cameras: dict[str, CameraCalibration] = {}
    """Per camera id."""
    wall: WallConfig | None = None
    """The wall, replacing the rig file's."""
    pointer_colours: PointerColours | None = None
    """The pointer's colours in this room (`trackerd calibrate pointer`)."""


def horizontal_focal_px(intrinsics: FovIntrinsics, width_px: int) -> float:
    """Focal length in pixels implied by a field of view (eq. 14 inverted)."""
    return (width_px / 2.0) / math.tan(math.radians(intrinsics.horizontal_fov_deg) / 2.0)
