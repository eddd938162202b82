"""Loading rig and calibration files from TOML, with errors an operator can act on.

``load_rig(path)`` reads the rig file, reads the calibration file it names (if
any), lets the calibration's values replace the rig's, and checks that every
camera ends up with intrinsics and extrinsics. Any problem raises
:class:`~trackerd.errors.ConfigError` with one line of the form::

    rig.toml: cameras[1].pixel_format: Mono8 is monochrome and cannot ...
"""

from __future__ import annotations

import datetime
import difflib
import json
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar, get_args, get_origin

from pydantic import BaseModel, ValidationError

from trackerd.config.models import (
    CALIBRATION_ONLY_FORMAT,
    COLOUR_PIXEL_FORMATS,
    CalibrationFile,
    ColourThreshold,
    PointerColours,
    RigConfig,
    ZmqOutput,
)
from trackerd.errors import CalibrationPending, ConfigError
from trackerd.files import MAX_DEPTH, NotRegularFile, TooLarge, nesting_depth, read_bounded

ModelT = TypeVar("ModelT", bound=BaseModel)


@dataclass(frozen=True)
class LoadedRig:
    """A validated rig, where it came from, and where each camera's calibration came from."""

    config: RigConfig
    path: Path
    calibration_path: Path | None
    sources: dict[str, str]
    """camera id (and 'wall') -> a short phrase naming the file its geometry was taken from."""
    threshold_sources: dict[str, str] | None = None
    """'red' / 'blue' -> where the detector's threshold for that end comes from: 'rig file'
    ([detector.<colour>]), 'learned' (pointer_colours) or 'default'."""


MAX_TOML_BYTES = 4 * 1024 * 1024
"""A rig or calibration file is a few kilobytes; one of megabytes is not one (and would be parsed on
the daemon's main thread at a SIGHUP)."""


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file, turning I/O and syntax problems into one-line ConfigErrors.

    Only a regular file of at most :data:`MAX_TOML_BYTES`, nested at most ``MAX_DEPTH`` levels, is
    read (trackerd.files): never a FIFO, which would block the reader until someone writes to it.
    """
    try:
        text = read_bounded(path, MAX_TOML_BYTES).decode("utf-8")
        data = tomllib.loads(text)
    except FileNotFoundError as err:
        raise ConfigError(f"{path}: no such file") from err
    except IsADirectoryError as err:
        raise ConfigError(f"{path}: is a directory, expected a TOML file") from err
    except PermissionError as err:
        raise ConfigError(f"{path}: permission denied") from err
    except (NotRegularFile, TooLarge) as err:
        raise ConfigError(f"{err}; expected a TOML file") from err
    except OSError as err:
        raise ConfigError(f"{path}: cannot read: {err.strerror or err}") from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: not valid TOML: {err}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"{path}: not a text file (UTF-8 expected)") from err
    except RecursionError as err:
        raise ConfigError(f"{path}: nested too deeply to be a rig or calibration file") from err
    except ValueError as err:
        # Not a TOMLDecodeError: tomllib reads an integer with int(), which refuses one of more than
        # sys.get_int_max_str_digits() digits (4300) with a plain ValueError.
        raise ConfigError(f"{path}: not valid TOML: {str(err).split(';')[0]}") from err
    if nesting_depth(data) > MAX_DEPTH:
        raise ConfigError(f"{path}: nested more than {MAX_DEPTH} levels deep; not a rig or calibration file")
    return data


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def key_text(key: object) -> str:
    """A key as TOML spells it: bare when it can be, quoted with escapes otherwise. A file may hold any
    key (a line break, a control character, nothing at all), and an error naming it must stay one line."""
    text = str(key)
    return text if _BARE_KEY.fullmatch(text) else json.dumps(text)


def quoted(text: object) -> str:
    """``'text'`` as a message quotes a key or a tag the file gave; JSON-escaped in double quotes when it
    holds anything that is not printable (a line break, a control character, U+2028) or a quote."""
    text = str(text)
    return f"'{text}'" if text.isprintable() and "'" not in text else json.dumps(text)


def format_location(loc: tuple[int | str, ...]) -> str:
    """``('cameras', 1, 'intrinsics', 'opencv', 'fx_px')`` -> ``cameras[1].intrinsics.fx_px``.

    The discriminator tag pydantic inserts for tagged unions ('opencv' above) is
    dropped, because it is not a key the user wrote.
    """
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif part in ("fov", "opencv", "pose") and text.endswith(("intrinsics", "extrinsics")):
            continue
        else:
            text += f".{key_text(part)}" if text else key_text(part)
    return text or "(top level)"


def _model_at(model: type[BaseModel], loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """Walk a model class along an error location to find the model that owns the last key."""
    current: Any = model
    for part in loc[:-1]:
        if isinstance(part, int) or current is None:
            continue
        if isinstance(current, type) and issubclass(current, BaseModel):
            field = current.model_fields.get(str(part))
            if field is None:
                # a discriminator tag, or a dict key such as a camera id
                current = _union_member(current, str(part)) or current
                continue
            current = _unwrap(field.annotation)
        else:
            current = _union_member(current, str(part))
    if isinstance(current, type) and issubclass(current, BaseModel):
        return current
    return None


def _unwrap(annotation: Any) -> Any:
    """The BaseModel class inside Optional[...], tuple[...], dict[str, ...] or Annotated unions."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    args = [a for a in get_args(annotation) if a is not type(None)]
    models = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
    if len(models) == 1:
        return models[0]
    if models:
        return tuple(models)
    for arg in args:
        inner = _unwrap(arg)
        if inner is not None:
            return inner
    if get_origin(annotation) is None:
        return None
    return None


def _union_member(current: Any, tag: str) -> Any:
    """Pick the member of a tagged union whose tag value is ``tag``."""
    candidates = current if isinstance(current, tuple) else ()
    for member in candidates:
        for name in ("model", "kind"):
            field = member.model_fields.get(name)
            if field is not None and tag in get_args(field.annotation):
                return member
    return None


def _union_tags(root: type[BaseModel], loc: tuple[int | str, ...], key: str) -> list[str]:
    """The values of the tag ``key`` that select the members of the tagged union at ``loc``."""
    owner = _model_at(root, loc)
    field = owner.model_fields.get(str(loc[-1])) if owner else None
    members = _unwrap(field.annotation) if field is not None else None
    members = members if isinstance(members, tuple) else ()
    tags: list[str] = []
    for member in members:
        if key in member.model_fields:
            tags += get_args(member.model_fields[key].annotation)
    return tags


def _meant_key(root: type[BaseModel], loc: tuple[int | str, ...]) -> tuple[int | str, ...] | None:
    """Where the key a misspelt one at ``loc`` was meant to be, or None when nothing is close."""
    owner = _model_at(root, loc)
    close = difflib.get_close_matches(str(loc[-1]), list(owner.model_fields) if owner else [], n=1)
    return (*loc[:-1], close[0]) if close else None


def describe_validation_error(err: ValidationError, root: type[BaseModel]) -> str:
    """The first error as ``key.path: what is wrong (allowed ...)``, plus a count of the rest."""
    errors = err.errors(include_url=False)
    # pydantic also reports a tuple whose items failed as too short ("... after validation,
    # not 0"); that follows from the item errors and is not a problem of its own.
    locs = [tuple(e["loc"]) for e in errors]

    def echoes_items(e: Any) -> bool:
        loc = tuple(e["loc"])
        inner = [o for o in locs if len(o) > len(loc) and o[: len(loc)] == loc]
        return e["type"] == "too_short" and bool(inner)

    errors = [e for e in errors if not echoes_items(e)] or errors
    # A misspelt key also shows up as the real key "missing": one problem, not two (for each
    # misspelling, not only the one reported). Report the misspelling first.
    meant = {_meant_key(root, tuple(e["loc"])) for e in errors if e["type"] == "extra_forbidden"}
    errors = [e for e in errors if not (e["type"] == "missing" and tuple(e["loc"]) in meant)]
    errors.sort(key=lambda e: e["type"] != "extra_forbidden")
    first = errors[0]
    loc = tuple(first["loc"])
    where = format_location(loc)
    kind = first["type"]
    if kind == "extra_forbidden":
        owner = _model_at(root, loc)
        names = list(owner.model_fields) if owner else []
        allowed = ", ".join(names) if names else "see docs/configuration.md"
        meant_here = _meant_key(root, loc)
        hint = f" (did you mean '{meant_here[-1]}'?)" if meant_here else ""
        message = f"unknown key {quoted(loc[-1])}{hint}; allowed keys here: {allowed}"
    elif kind == "missing" and isinstance(loc[-1], int):
        # A fixed-length array (a 3-vector, the four corners) with too few values: pydantic
        # reports each absent item; say once how many values were wanted.
        parent = loc[:-1]
        absent = [e for e in errors if e["type"] == "missing" and tuple(e["loc"][:-1]) == parent]
        errors = [e for e in errors if e not in absent[1:]]
        given = first.get("input")
        count = len(given) if isinstance(given, (list, tuple)) else loc[-1]
        where = format_location(parent)
        message = f"needs {count + len(absent)} values, got {count}"
    elif kind == "missing":
        message = "required key is missing"
    elif kind == "union_tag_invalid":
        # pydantic's message quotes the tag as given, line breaks and all.
        ctx = first.get("ctx", {})
        message = (f"tag {quoted(ctx.get('tag', ''))} in key {ctx.get('discriminator', '')} does not match"
                   f" any of the expected tags: {ctx.get('expected_tags', '')}")
    elif kind == "union_tag_not_found":
        key = str(first.get("ctx", {}).get("discriminator", "")).strip("'")
        tags = _union_tags(root, loc, key)
        allowed = f" (one of {', '.join(repr(t) for t in tags)})" if tags else ""
        message = f"required key '{key}' is missing; it selects the form{allowed}"
    elif kind in TOML_TYPE_NAMES:
        message = f"must be {TOML_TYPE_NAMES[kind]}"
        value = first.get("input")
        if not isinstance(value, (dict, list)):
            message += f" (got {_toml_literal(value)})"
    else:
        message = first["msg"]
        if message.startswith("Value error, "):
            message = message[len("Value error, ") :]
        value = first.get("input")
        if kind not in ("value_error",) and isinstance(value, (str, int, float)):
            message += f" (got {value!r})"
    more = len(errors) - 1
    suffix = f" (and {more} more problem{'s' if more > 1 else ''})" if more else ""
    return f"{where}: {message}{suffix}"


TOML_TYPE_NAMES = {
    "int_type": "an integer",
    "int_from_float": "an integer",
    "float_type": "a number",
    "bool_type": "true or false",
    "string_type": "a string",
    "dict_type": "a table",
    "model_type": "a table",
    "model_attributes_type": "a table",
    "list_type": "an array",
    "tuple_type": "an array",
}
"""pydantic's type errors (JSON-mode wording: "a valid dictionary", "an object") in TOML's terms."""


def _toml_literal(value: Any) -> str:
    """A value as the rig file spells it: ``"0.45"``, ``true``, ``7.0``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def _strictly(model: type[ModelT], data: dict[str, Any]) -> ModelT:
    """Validate file data with no type coercion: ``width_px = "1920"`` or ``clutter = true`` is a
    type error, not a 1920 or a 1.

    Strict validation in pydantic's JSON mode still takes what a file can only spell one way (an
    array for a tuple, a string for a path, an integer for a float), so the data goes through
    JSON; TOML's dates and times, which no setting takes, become their ISO strings.
    """
    text = json.dumps(data, default=_json_fallback, allow_nan=True)
    return model.model_validate_json(text, strict=True)


def _json_fallback(value: Any) -> str:
    if isinstance(value, (datetime.date, datetime.time)):
        return value.isoformat()
    raise TypeError(f"cannot validate a {type(value).__name__}")


def parse_rig(data: dict[str, Any], path: Path) -> RigConfig:
    """Validate rig data read from ``path``; errors name the file."""
    try:
        rig = _strictly(RigConfig, data)
    except ValidationError as err:
        raise ConfigError(f"{path}: {describe_validation_error(err, RigConfig)}") from err
    return rig if rig.pointer_colours is None else with_learned_colours(rig, rig.pointer_colours)


def with_learned_colours(rig: RigConfig, colours: PointerColours) -> RigConfig:
    """The rig with the pointer's learned colours, and the detector's threshold for each end taken from
    them unless the rig file gives ``[detector.red]`` / ``[detector.blue]`` itself (those stay overrides)."""
    given = rig.detector.model_fields_set
    learned = {
        colour: ColourThreshold(min_excess=colours.of(colour).min_excess, min_value=colours.of(colour).min_value)
        for colour in ("red", "blue")
        if colour not in given
    }
    return rig.model_copy(update={"pointer_colours": colours, "detector": rig.detector.model_copy(update=learned)})


def parse_calibration(data: dict[str, Any], path: Path) -> CalibrationFile:
    """Validate calibration data read from ``path``; errors name the file."""
    try:
        return _strictly(CalibrationFile, data)
    except ValidationError as err:
        raise ConfigError(f"{path}: {describe_validation_error(err, CalibrationFile)}") from err


def load_calibration(path: Path) -> CalibrationFile:
    """Read and validate a calibration file on its own."""
    return parse_calibration(read_toml(path), path)


def load_rig(path: str | Path, *, for_tracking: bool = True) -> LoadedRig:
    """Read a rig file, merge its calibration file, and check the result can track.

    A rig that is valid but not ready to track (a calibration step still to run, no [wall] or
    [pointer], Mono8 cameras) raises CalibrationPending naming the first thing left, after everything
    that can be checked has been. ``for_tracking=False`` returns such a rig as it is, for commands that
    use only its cameras (``trackerd record``, ``recording import``: a board recorded for calibration).
    """
    rig_path = Path(path)
    data = read_toml(rig_path)
    rig = parse_rig(data, rig_path)
    detector_table = data.get("detector") if isinstance(data.get("detector"), dict) else {}
    sources = {cam.id: f"inline in {rig_path.name}" for cam in rig.cameras}
    sources["wall"] = f"inline in {rig_path.name}"
    calibration_path: Path | None = None
    not_ready: list[CalibrationPending] = []
    frame = None
    if rig.calibration is not None:
        calibration_path = (rig_path.parent / rig.calibration).resolve()
        if not calibration_path.exists():
            not_ready.append(CalibrationPending(
                rig_path,
                f"calibration: {calibration_path}: no such file yet (the path is relative to the rig file);"
                f" `trackerd calibrate intrinsics --config {rig_path.name} --camera {rig.cameras[0].id}` writes it",
            ))
        else:
            calibration = load_calibration(calibration_path)
            rig = merge_calibration(rig, calibration, calibration_path)
            for camera_id, entry in calibration.cameras.items():
                given = [part for part in ("intrinsics", "extrinsics") if getattr(entry, part)]
                if len(given) == 2:
                    sources[camera_id] = f"from {calibration_path.name}"
                elif given:
                    kept = "extrinsics" if given[0] == "intrinsics" else "intrinsics"
                    sources[camera_id] = (
                        f"{given[0]} from {calibration_path.name}, {kept} inline in {rig_path.name}"
                    )
            if calibration.wall is not None:
                sources["wall"] = f"from {calibration_path.name}"
            frame = _unfinished_frame(calibration)
    # In the order the steps run: every lens, then the poses, then what only colour cameras can do.
    for part in ("intrinsics", "extrinsics"):
        for index, cam in enumerate(rig.cameras):
            if getattr(cam, part) is None:
                where = f" or in {calibration_path}" if calibration_path else ""
                step = f"intrinsics --camera {cam.id}" if part == "intrinsics" else "stereo"
                not_ready.append(CalibrationPending(
                    rig_path,
                    f"cameras[{index}] ('{cam.id}') has no {part}; give them in"
                    f" [cameras.{part}]{where} (a calibration file named by 'calibration'), or run"
                    f" `trackerd calibrate {step} --config {rig_path.name}`",
                ))
    for index, cam in enumerate(rig.cameras):
        if cam.pixel_format == CALIBRATION_ONLY_FORMAT:
            not_ready.append(CalibrationPending(
                rig_path,
                f"cameras[{index}].pixel_format: {cam.pixel_format} is monochrome and cannot tell"
                f" the pointer's red end from its blue end; use one of {', '.join(COLOUR_PIXEL_FORMATS)}"
                f" to track ({cam.pixel_format} is fine for `trackerd calibrate intrinsics` and `stereo`; `calibrate"
                " wall` locates the pointer, so it needs colour too)",
            ))
    if frame is not None:
        # After `calibrate stereo` on a rig without poses the cameras are in camera 1's frame and the
        # rig's wall, in its own frame, does not match them: not a wrong wall, a step still to come.
        tables = [f"[{t}]" for t, v in (("wall", rig.wall), ("pointer", rig.pointer)) if v is None]
        first = f" (it needs {' and '.join(tables)} in {rig_path.name} first: the wall's nominal size, the pointer)"
        not_ready.append(CalibrationPending(
            calibration_path,
            f"the cameras are in {frame}'s frame (as `trackerd calibrate stereo` left them)"
            f" and the wall is not calibrated in it yet; next: `trackerd calibrate wall --config {rig_path.name}`"
            + (first if tables else ""),
        ))
    for table, given in (("wall", rig.wall), ("pointer", rig.pointer)):
        if given is None:
            where = " (here, or in the calibration file from `trackerd calibrate wall`)" if table == "wall" else ""
            not_ready.append(CalibrationPending(
                rig_path,
                f"{table}: required table is missing{where}; tracking needs it"
                " (config/datawall.toml has one to copy)",
            ))
    # What can be checked is checked either way: every lens there is, and the wall against the cameras
    # once every camera is posed in the wall's frame.
    posed = all(cam.intrinsics is not None and cam.extrinsics is not None for cam in rig.cameras)
    # Imported here, not at the top: importing any config model runs this module, and NumPy and
    # OpenCV take a quarter of a second to import.
    from trackerd.config.rig_geometry import check_lens, check_wall_in_front

    if posed and rig.wall is not None and frame is None:
        check_wall_in_front(rig, rig_path if "inline" in sources["wall"] else calibration_path)
    rig = _resolve_paths(rig, rig_path)
    for index, cam in enumerate(rig.cameras):
        if cam.intrinsics is None or cam.extrinsics is None:
            continue
        from_calibration = sources[cam.id].startswith(("from ", "intrinsics from "))
        if from_calibration:
            check_lens(cam, f"{calibration_path}: cameras.{cam.id}")
        else:
            check_lens(cam, f"{rig_path}: cameras[{index}]")
    if not_ready and for_tracking:
        raise not_ready[0]
    thresholds = {
        colour: "rig file" if colour in detector_table else "learned" if rig.pointer_colours else "default"
        for colour in ("red", "blue")
    }
    return LoadedRig(rig, rig_path, calibration_path, sources, thresholds)


def check_ready_to_track(rig: RigConfig, where: object) -> None:
    """For a rig assembled elsewhere (a recording's): CalibrationPending unless it can track as load_rig
    would have it (wall, pointer, every camera's lens and pose, colour), then the geometric checks."""
    for table in ("wall", "pointer"):
        if getattr(rig, table) is None:
            raise CalibrationPending(where, f"{table}: required table is missing; tracking needs it")
    for index, cam in enumerate(rig.cameras):
        missing = [part for part in ("intrinsics", "extrinsics") if getattr(cam, part) is None]
        if missing:
            raise CalibrationPending(where, f"cameras[{index}] ('{cam.id}') has no {' or '.join(missing)}")
        if cam.pixel_format == CALIBRATION_ONLY_FORMAT:
            raise CalibrationPending(
                where, f"cameras[{index}].pixel_format: Mono8 cannot tell the pointer's red end from its blue end"
            )
    from trackerd.config.rig_geometry import check_rig_geometry  # here, not at the top: as in load_rig

    check_rig_geometry(rig, Path(str(where)))


def _unfinished_frame(calibration: CalibrationFile) -> str | None:
    """'camera <id>' when a calibration file has cameras in camera 1's frame and no wall in it."""
    if calibration.wall is not None:
        return None
    for entry in calibration.cameras.values():
        frame = str(entry.info.get("world_frame", ""))
        if frame.startswith("camera ") and entry.extrinsics is not None:
            return frame
    return None


def _resolve_paths(rig: RigConfig, rig_path: Path) -> RigConfig:
    """File names inside a rig file are relative to that file, like ``calibration``."""
    def resolved(model, keys):
        return {
            key: (rig_path.parent / value).resolve()
            for key in keys
            if (value := getattr(model, key)) is not None and not Path(value).is_absolute()
        }

    zmq = rig.outputs.zmq
    zmq_update = resolved(zmq, ("curve_secret_key_file", "curve_authorized_keys_dir"))
    gestures = rig.interaction.gestures
    gestures_update = resolved(gestures, ("template_dir",))
    update: dict[str, Any] = {}
    if zmq_update:
        update["outputs"] = rig.outputs.model_copy(update={"zmq": zmq.model_copy(update=zmq_update)})
    if gestures_update:
        update["interaction"] = rig.interaction.model_copy(
            update={"gestures": gestures.model_copy(update=gestures_update)}
        )
    return rig.model_copy(update=update) if update else rig


def merge_calibration(rig: RigConfig, calibration: CalibrationFile, path: Path) -> RigConfig:
    """The rig with each camera's intrinsics/extrinsics (and the wall) replaced by the calibration's."""
    known = {cam.id for cam in rig.cameras}
    unknown = sorted(set(calibration.cameras) - known)
    if unknown:
        raise ConfigError(
            f"{path}: cameras.{key_text(unknown[0])}: no camera with this id in the rig"
            f" (the rig has {', '.join(sorted(known))})"
        )
    cameras = []
    for cam in rig.cameras:
        entry = calibration.cameras.get(cam.id)
        if entry is None:
            cameras.append(cam)
            continue
        update = {k: getattr(entry, k) for k in ("intrinsics", "extrinsics") if getattr(entry, k)}
        cameras.append(cam.model_copy(update=update))
    if calibration.pointer_colours is not None:
        if rig.pointer_colours is not None:
            raise ConfigError(
                f"{path}: pointer_colours: the rig file gives them too; keep one"
                " (`trackerd calibrate pointer` writes them into the calibration file)"
            )
        rig = with_learned_colours(rig, calibration.pointer_colours)
    update: dict[str, Any] = {"cameras": tuple(cameras)}
    if calibration.wall is not None:
        update["wall"] = calibration.wall
    # Re-validate so cross-field checks (principal point inside the image) see the merged values.
    try:
        return RigConfig.model_validate(rig.model_copy(update=update).model_dump())
    except ValidationError as err:
        raise ConfigError(
            f"{path}: after merging into the rig: {describe_validation_error(err, RigConfig)}"
        ) from err


def with_endpoints(rig: RigConfig, endpoints: list[str], option: str = "--endpoint") -> RigConfig:
    """The rig publishing on ``endpoints`` instead of its own, checked as the rig file's are
    (a network address needs CURVE or allow_insecure_network); ConfigError naming ``option``."""
    try:
        zmq_config = ZmqOutput.model_validate({**rig.outputs.zmq.model_dump(), "endpoints": tuple(endpoints)})
    except ValidationError as err:
        problem = describe_validation_error(err, ZmqOutput).removeprefix("(top level): ")
        raise ConfigError(f"{option}: {problem}") from err
    return rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_config})})


def dump_rig(rig: RigConfig, header: str = "") -> str:
    """A rig as TOML text that load_rig reads back to the same rig (defaults left out).

    The ``calibration`` path is written as it is; make it absolute first if the text
    is saved somewhere else than the original rig file's directory.
    """
    from trackerd.config.tomlwrite import dumps

    return dumps(rig.model_dump(mode="json", exclude_none=True, exclude_defaults=True), header=header)


def with_console(rig: RigConfig, listen: str | None, option: str = "--console") -> RigConfig:
    """The rig with its console moved to ``listen`` (HOST:PORT), or switched off ('off'), checked
    as the rig file's ``[console]`` is; None leaves it as it is. ConfigError naming ``option``."""
    from trackerd.config.console import ConsoleConfig

    if listen is None:
        return rig
    if listen.strip().lower() == "off":
        update: dict[str, Any] = {"enabled": False}
    else:
        update = {"enabled": True, "listen": listen}
    try:
        # Only what was set: a listen address not given stays the default (serve() runs on without
        # the console when the default port is taken, and fails when a chosen one is).
        console = ConsoleConfig.model_validate({**rig.console.model_dump(exclude_unset=True), **update})
    except ValidationError as err:
        problem = describe_validation_error(err, ConsoleConfig).removeprefix("(top level): ")
        raise ConfigError(f"{option}: {problem}") from err
    return rig.model_copy(update={"console": console})
