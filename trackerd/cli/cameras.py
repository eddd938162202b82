"""`trackerd cameras [CAMERA] [--json] [--producer CTI]`: the cameras Aravis, pylon and GenTL producers offer,
and what one of them offers."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from trackerd.acquisition.discovery import (
    ADDRESS_PROBE_TIMEOUT_S,
    ADDRESS_PROBE_TRIES,
    CameraDetails,
    DeviceEntry,
    describe_camera,
    device_at,
    find_device,
    is_ipv4_address,
    list_devices,
)
from trackerd.acquisition.pylon import pylon_missing_reason
from trackerd.errors import CameraError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "cameras",
        help="list the cameras Aravis (GigE Vision, USB3 Vision) and pylon see",
        description="List every camera Aravis discovers, and those pylon finds when the trackerd[gentl] extra is"
        " installed (with the rig file's backend that reaches each); with CAMERA, also what it offers "
        "(pixel formats, resolution range, frame rate, exposure, gain, trigger and PTP support).",
    )
    parser.add_argument("camera", nargs="?", help="device id, serial number or IP address of one camera")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--fake", action="store_true", help="include Aravis's built-in Fake camera (for trying the command)"
    )
    parser.add_argument(
        "--producer",
        action="append",
        default=[],
        metavar="CTI",
        help="also list the devices this GenTL producer (a frame grabber's .cti file) offers, for backend ="
        " 'gentl' (the trackerd[gentl] extra); may be given more than once",
    )
    parser.set_defaults(handler=cameras_command)


def cameras_command(args: argparse.Namespace) -> int:
    if args.camera and is_ipv4_address(args.camera):
        return _camera_at(args.camera, args.json)
    devices = list_devices(include_fake=args.fake, producers=args.producer)
    if not devices:
        message = (
            "no camera found: Aravis sees no GigE Vision or USB3 Vision device"
            " (check cabling, the NIC's address and subnet, and the firewall for UDP port 3956;"
            " docs/acquisition.md)"
        )
        if pylon_missing_reason() is None:
            message += "; pylon finds no camera either"
        if args.producer:
            message += f"; {', '.join(args.producer)} offer{'s' if len(args.producer) == 1 else ''} no device either"
        if args.camera and not args.json:
            # Asked about one camera: an error about that camera, like any other not found.
            raise CameraError(f"no camera '{args.camera}': {message.removeprefix('no camera found: ')}")
        if args.json:
            print(json.dumps({"cameras": [], "error": message}))
        else:
            print(message)
        return 1
    details = None
    if args.camera:
        device = find_device(devices, args.camera)
        if device is None:
            known = ", ".join(d.serial or d.device_id for d in devices)
            raise CameraError(f"no camera '{args.camera}' among those found ({known})")
        details = describe_camera(device)
    if args.json:
        out: dict = {"cameras": [asdict(d) for d in devices]}
        if details is not None:
            out["camera"] = details.to_dict()
        print(json.dumps(out, indent=2))
    else:
        print(format_devices(devices))
        if details is not None:
            print()
            print(format_details(details))
    return 0


def _camera_at(address: str, as_json: bool) -> int:
    """One camera named by its address: asked directly, not looked for by broadcast discovery.

    Broadcast discovery stops at the host's own subnets, so a routed camera that
    Aravis opens by its address would otherwise be reported as absent (issue 15).
    """
    device = device_at(address)
    if device is None:
        waited_s = ADDRESS_PROBE_TRIES * ADDRESS_PROBE_TIMEOUT_S
        raise CameraError(
            f"no camera answers at {address}: no GVCP discovery answer from UDP port 3956 in {waited_s:g} s"
            f" (check the address, that this host has a route to it: ip route get {address},"
            " and that no firewall drops UDP port 3956 either way; docs/acquisition.md)"
        )
    details = describe_camera(device)
    if as_json:
        print(json.dumps({"cameras": [asdict(device)], "camera": details.to_dict()}, indent=2))
    else:
        print(format_devices([device], where=f"at {address}"))
        print()
        print(format_details(details))
    return 0


def format_devices(devices: list[DeviceEntry], where: str = "") -> str:
    header = ("device id", "vendor", "model", "serial", "address", "protocol", "backend")
    rows = [header] + [(d.device_id, d.vendor, d.model, d.serial, d.address, d.protocol, d.backend) for d in devices]
    producers = sorted({d.producer for d in devices if d.producer})
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    lines = ["  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip() for row in rows]
    found = f"{len(devices)} camera{'s' if len(devices) != 1 else ''} found{' ' + where if where else ''}"
    notes = [f"backend gentl: producer = {p!r}" for p in producers]
    return found + "\n" + "\n".join(lines + notes)


def _range(bounds: tuple[float, float] | None, unit: str) -> str:
    return "not settable" if bounds is None else f"{bounds[0]:g} - {bounds[1]:g}{unit}"


def format_details(d: CameraDetails) -> str:
    return "\n".join(
        [
            f"{d.device_id}: {d.vendor} {d.model}, serial {d.serial} ({d.protocol})",
            f"  sensor          {d.sensor_px[0]}x{d.sensor_px[1]} px",
            f"  width           {d.width_px[0]} - {d.width_px[1]} px in steps of {d.width_px[2]}",
            f"  height          {d.height_px[0]} - {d.height_px[1]} px in steps of {d.height_px[2]}",
            f"  pixel formats   {', '.join(d.pixel_formats) or 'none listed'} (now {d.pixel_format})",
            f"  frame rate      {_range(d.frame_rate_hz, ' Hz')}",
            f"  exposure        {_range(d.exposure_us, ' us')}",
            f"  gain            {_range(d.gain, '')}",
            f"  triggers        {', '.join(d.triggers) or 'none'}",
            f"  trigger sources {', '.join(d.trigger_sources) or 'none'}"
            f"{' (software trigger supported)' if d.software_trigger else ''}",
            f"  trigger edges   {', '.join(d.trigger_activations) or 'not settable'}",
            f"  PTP (IEEE 1588) {d.ptp or 'not supported'}",
            f"  GigE transport  packet size {d.packet_size_bytes or 'n/a'} bytes,"
            f" packet delay {'settable' if d.packet_delay else 'not settable'}",
        ]
    )
