#!/bin/sh
# Run a command inside an approximation of trackerd.service's sandbox (tests/systemd/test_sandbox.py).
# Needs root; call it through `unshare --net --mount --pid --fork --propagation private`, which
# gives private network, mount and PID namespaces.
#   ProtectSystem=strict   every mount read-only except /dev, /proc, /run and the private /tmp
#   ProtectHome=yes        empty, read-only /home and /root
#   PrivateTmp=yes         fresh /tmp and /var/tmp
#   PrivateDevices=yes     a /dev with null, zero, full, random, urandom, tty and shm only
#   ProtectProc=invisible, ProcSubset=pid   /proc shows own processes only, no /proc/sys, /proc/cpuinfo
#   RuntimeDirectory=trackerd               a writable /run/trackerd owned by the service user
# Environment:
#   SANDBOX_NOTIFY_DIR   a host directory made visible as /run/notify (sd_notify's socket lives there)
#   SANDBOX_FAKE_CAMERA  a serial: start Aravis's fake GigE Vision camera on 127.0.0.1 first
#                        (outside the service's restrictions, as a real camera would be)
# Usage: sandbox.sh UID GID COMMAND...
set -eu
uid=$1 gid=$2
shift 2

ip link set lo up
if [ -n "${SANDBOX_FAKE_CAMERA:-}" ]; then
    arv-fake-gv-camera-0.8 -i 127.0.0.1 -s "$SANDBOX_FAKE_CAMERA" >/dev/null 2>&1 &
fi

mount -t proc -o hidepid=invisible,subset=pid proc /proc
mount -t tmpfs -o mode=0755,nosuid,nodev tmpfs /run
mkdir -m 0750 /run/trackerd
chown "$uid:$gid" /run/trackerd
if [ -n "${SANDBOX_NOTIFY_DIR:-}" ]; then
    mkdir /run/notify
    mount --bind "$SANDBOX_NOTIFY_DIR" /run/notify
fi
mkdir /run/dev
mount -t tmpfs -o mode=0755,nosuid tmpfs /run/dev
for node in null zero full random urandom tty; do
    touch "/run/dev/$node"
    mount --bind "/dev/$node" "/run/dev/$node"
done
mkdir /run/dev/shm
mount -t tmpfs -o mode=1777,nosuid,nodev tmpfs /run/dev/shm
mount --move /run/dev /dev
rmdir /run/dev
# A bind remount changes one mount only, so every mount is made read-only in turn.
awk '{print $2}' /proc/self/mounts | while read -r mp; do
    case "$mp" in /proc|/proc/*|/dev|/dev/*|/run|/run/*) continue ;; esac
    mount -o remount,bind,ro "$mp" 2>/dev/null || true
done
for dir in /tmp /var/tmp; do mount -t tmpfs -o mode=1777,nosuid,nodev tmpfs "$dir"; done
for dir in /home /root; do
    if [ -d "$dir" ]; then mount -t tmpfs -o mode=0755,ro tmpfs "$dir"; fi
done
[ -z "${SANDBOX_FAKE_CAMERA:-}" ] || sleep 0.5  # let the camera answer before the probe looks
exec "$@"
