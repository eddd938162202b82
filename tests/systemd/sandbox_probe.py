"""Runs inside tests/systemd/sandbox.sh: applies trackerd.service's process restrictions to itself,
then exercises what the daemon uses (PyGObject + Aravis over UDP, NumPy, OpenCV, pyzmq with CURVE on
tcp and ipc, sd_notify) and prints one JSON object of check -> "ok" or the error.

Usage: sandbox_probe.py UNIT_FILE CAMERA_ADDRESS NOTIFY_SOCKET < SYSCALLS_JSON

Standard input holds {"allow": [...], "deny": [...]}: the unit's SystemCallFilter groups expanded by
systemd-analyze (outside the sandbox, where it can run).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import json
import os
import socket
import sys
import traceback

SCMP_ACT_ALLOW = 0x7FFF0000
SCMP_CMP_EQ = 4
SCMP_CMP_MASKED_EQ = 7
PROT_WRITE, PROT_EXEC = 0x2, 0x4
SHM_EXEC = 0o100000
SCHED_FIFO, SCHED_RR, SCHED_DEADLINE, SCHED_RESET_ON_FORK = 1, 2, 6, 0x40000000
FAMILIES = {"AF_UNIX": 1, "AF_INET": 2, "AF_INET6": 10, "AF_NETLINK": 16, "AF_PACKET": 17}
AF_MAX = 46


def errno_action(code: int) -> int:
    return 0x00050000 | (code & 0xFFFF)


class ArgCmp(ctypes.Structure):
    _fields_ = [("arg", ctypes.c_uint), ("op", ctypes.c_int), ("a", ctypes.c_uint64), ("b", ctypes.c_uint64)]


def load_seccomp():
    lib = ctypes.CDLL(ctypes.util.find_library("seccomp") or "libseccomp.so.2", use_errno=True)
    lib.seccomp_init.restype = ctypes.c_void_p
    lib.seccomp_init.argtypes = [ctypes.c_uint32]
    lib.seccomp_rule_add_array.argtypes = [
        ctypes.c_void_p,
        ctypes.c_uint32,
        ctypes.c_int,
        ctypes.c_uint,
        ctypes.POINTER(ArgCmp),
    ]
    lib.seccomp_load.argtypes = [ctypes.c_void_p]
    lib.seccomp_release.argtypes = [ctypes.c_void_p]
    lib.seccomp_syscall_resolve_name.argtypes = [ctypes.c_char_p]
    return lib


def unit_settings(path: str) -> dict[str, list[str]]:
    settings: dict[str, list[str]] = {}
    section = ""
    with open(path, encoding="utf-8") as handle:
        lines = handle.read().splitlines()
    for raw in lines:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("["):
            section = line
            continue
        if section == "[Service]" and "=" in line:
            key, value = line.split("=", 1)
            settings.setdefault(key, []).append(value)
    return settings


def apply_restrictions(settings: dict[str, list[str]], syscalls: dict[str, list[str]]) -> list[str]:
    """Install seccomp filters like systemd 252 does for this unit; returns what was applied."""
    lib = load_seccomp()
    applied = []

    def rule(ctx, action, name, *cmps):
        nr = lib.seccomp_syscall_resolve_name(name.encode())
        if nr < 0:
            return
        array = (ArgCmp * max(len(cmps), 1))(*cmps)
        rc = lib.seccomp_rule_add_array(ctx, action, nr, len(cmps), array)
        if rc != 0:
            raise OSError(-rc, f"seccomp rule for {name}")

    ctx = lib.seccomp_init(SCMP_ACT_ALLOW)
    families = " ".join(settings.get("RestrictAddressFamilies", [])).split()
    if families:
        allowed = {FAMILIES[f] for f in families}
        for family in range(AF_MAX):
            if family not in allowed:
                rule(ctx, errno_action(errno.EAFNOSUPPORT), "socket", ArgCmp(0, SCMP_CMP_EQ, family, 0))
        applied.append("RestrictAddressFamilies")
    if settings.get("MemoryDenyWriteExecute", ["no"])[-1] == "yes":
        deny = errno_action(errno.EPERM)
        wx = PROT_WRITE | PROT_EXEC
        rule(ctx, deny, "mmap", ArgCmp(2, SCMP_CMP_MASKED_EQ, wx, wx))
        rule(ctx, deny, "mprotect", ArgCmp(2, SCMP_CMP_MASKED_EQ, PROT_EXEC, PROT_EXEC))
        rule(ctx, deny, "pkey_mprotect", ArgCmp(2, SCMP_CMP_MASKED_EQ, PROT_EXEC, PROT_EXEC))
        rule(ctx, deny, "shmat", ArgCmp(2, SCMP_CMP_MASKED_EQ, SHM_EXEC, SHM_EXEC))
        applied.append("MemoryDenyWriteExecute")
    if settings.get("RestrictRealtime", ["no"])[-1] == "yes":
        # Real-time policies are refused; SCHED_OTHER/BATCH/IDLE stay allowed (libzmq sets its
        # threads' policy at start even when unchanged, and aborts if that fails).
        for policy in (SCHED_FIFO, SCHED_RR, SCHED_DEADLINE):
            for flag in (0, SCHED_RESET_ON_FORK):
                rule(ctx, errno_action(errno.EPERM), "sched_setscheduler", ArgCmp(1, SCMP_CMP_EQ, policy | flag, 0))
        applied.append("RestrictRealtime")
    if lib.seccomp_load(ctx) != 0:
        raise OSError("seccomp_load (families, W^X, realtime) failed")
    # The allow list goes last: it forbids seccomp() itself, as systemd's does.
    if "SystemCallFilter" in settings:
        ctx = lib.seccomp_init(errno_action(errno.EPERM))
        for name in sorted(set(syscalls["allow"]) - set(syscalls["deny"])):
            rule(ctx, SCMP_ACT_ALLOW, name)
        if lib.seccomp_load(ctx) != 0:
            raise OSError("seccomp_load (syscall allow list) failed")
        lib.seccomp_release(ctx)
        applied.append("SystemCallFilter")
    return applied


def check(results: dict[str, str], name: str, func) -> None:
    try:
        outcome = func()
        results[name] = "ok" if outcome is None else f"ok: {outcome}"
    except Exception as err:  # noqa: BLE001 - the probe reports every failure instead of stopping at the first
        results[name] = f"FAILED: {type(err).__name__}: {err} | {traceback.format_exc(limit=3)!r}"


def main() -> int:
    unit, camera_address, notify_socket = sys.argv[1:4]
    settings = unit_settings(unit)
    syscalls = json.load(sys.stdin)
    # Everything is imported after the filters are in place, as in the daemon.
    results: dict[str, str] = {"uid": str(os.getuid())}
    results["applied"] = ",".join(apply_restrictions(settings, syscalls))

    def wx_refused():
        import mmap

        try:
            mmap.mmap(-1, 4096, prot=mmap.PROT_READ | mmap.PROT_WRITE | mmap.PROT_EXEC)
        except OSError:
            return "refused"
        if "MemoryDenyWriteExecute" in results["applied"]:
            raise AssertionError("a writable+executable mapping was allowed")
        return "allowed (MemoryDenyWriteExecute off)"

    def packet_socket_refused():
        try:
            socket.socket(socket.AF_PACKET, socket.SOCK_RAW).close()
        except OSError as err:
            return errno.errorcode.get(err.errno, str(err.errno))
        raise AssertionError("an AF_PACKET socket was created")

    def aravis_udp_stream():
        import gi

        gi.require_version("Aravis", "0.8")
        from gi.repository import Aravis

        camera = Aravis.Camera.new(camera_address)
        calls = []
        # A Python callback given to a C function: PyGObject builds a libffi closure for it.
        stream = camera.create_stream(lambda user_data, kind, buffer: calls.append(int(kind)), None)
        # As trackerd's acquisition does: a receive buffer sized for a whole frame (ordinary UDP
        # sockets here, since the service has no CAP_NET_RAW for Aravis's packet socket).
        stream.set_property("socket-buffer", Aravis.GvStreamSocketBuffer.AUTO)
        for _ in range(4):
            stream.push_buffer(Aravis.Buffer.new_allocate(camera.get_payload()))
        camera.start_acquisition()
        statuses = []
        # The first frames of a stream may be incomplete (the fake camera starts mid-frame).
        for _ in range(8):
            buffer = stream.timeout_pop_buffer(2_000_000)
            if buffer is None:
                statuses.append("timeout")
                continue
            statuses.append(buffer.get_status().value_nick)
            if buffer.get_status() == Aravis.BufferStatus.SUCCESS:
                break
            stream.push_buffer(buffer)
        camera.stop_acquisition()
        if statuses[-1] != "success":
            raise AssertionError(f"no complete frame in {len(statuses)}: {statuses}")
        if not calls:
            raise AssertionError("the stream callback (a libffi closure) never ran")
        size = f"{buffer.get_image_width()}x{buffer.get_image_height()}"
        return f"{camera.get_model_name()} frame {size} after {statuses}"

    def ctypes_closure():
        callback = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_int)(lambda x: x + 1)
        if callback(41) != 42:
            raise AssertionError("ctypes callback returned the wrong value")

    def numpy_opencv():
        import cv2
        import numpy as np

        image = np.random.default_rng(1).integers(0, 255, (1080, 1920), dtype=np.uint8)
        rgb = cv2.cvtColor(image, cv2.COLOR_BayerRG2RGB)
        solved = np.linalg.solve(np.eye(64) * 2.0, np.ones(64))
        return f"{rgb.shape}, {solved[0]}"

    def zmq_curve_tcp_and_ipc():
        import time

        import zmq

        from trackerd.config.models import ZmqOutput
        from trackerd.publish import HitMessage, Publisher

        public, secret = zmq.curve_keypair()
        key_file = "/run/trackerd/server.key_secret"
        fd = os.open(key_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.write(fd, f'curve\n    public-key = "{public.decode()}"\n    secret-key = "{secret.decode()}"\n'.encode())
        os.close(fd)
        config = ZmqOutput(
            endpoints=("tcp://127.0.0.1:*", "ipc:///run/trackerd/trackerd.sock"), curve_secret_key_file=key_file
        )
        hit = HitMessage(
            sequence=1,
            capture_ns=1,
            wall_x_m=1.0,
            wall_y_m=0.5,
            on_wall=True,
            distance_m=1.0,
            front_m=(1.0, 0.5, 1.0),
            back_m=(1.0, 0.5, 1.5),
            ray_gap_mm=1.0,
        )
        got = []
        with Publisher(config) as publisher:
            context = zmq.Context()
            for endpoint in publisher.endpoints:
                client_public, client_secret = zmq.curve_keypair()
                sub = context.socket(zmq.SUB)
                sub.curve_serverkey, sub.curve_publickey, sub.curve_secretkey = public, client_public, client_secret
                sub.subscribe(b"hit")
                sub.connect(endpoint)
                deadline = time.monotonic() + 5.0
                while time.monotonic() < deadline and not sub.poll(50):
                    publisher.publish(hit)
                if sub.poll(0):
                    got.append(sub.recv_multipart()[0])
                sub.close(linger=0)
            context.term()
        if got != [b"hit", b"hit"]:
            raise AssertionError(f"received {got} over {config.endpoints}")

    def sd_notify():
        from trackerd.sdnotify import SdNotify

        with SdNotify({"NOTIFY_SOCKET": notify_socket}) as notifier:
            if not notifier.ready("probe ready"):
                raise AssertionError("READY=1 could not be sent")

    def read_only_system():
        try:
            open("/usr/trackerd-probe", "w").close()
        except OSError as err:
            return errno.errorcode.get(err.errno, str(err.errno))
        raise AssertionError("/usr is writable")

    check(results, "wx_mapping", wx_refused)
    check(results, "packet_socket", packet_socket_refused)
    check(results, "read_only_system", read_only_system)
    check(results, "ctypes_closure", ctypes_closure)
    check(results, "aravis_udp_stream", aravis_udp_stream)
    check(results, "numpy_opencv", numpy_opencv)
    check(results, "zmq_curve_tcp_and_ipc", zmq_curve_tcp_and_ipc)
    check(results, "sd_notify", sd_notify)
    print(json.dumps(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
