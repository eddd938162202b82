"""scripts/install into a temporary root: the units as installed there pass `systemd-analyze verify`,
with the entry point pip made for them, and a re-run keeps the operator's files.

The install uses --no-deps: trackerd itself goes into the venv through pip, as in a real install,
so /opt/trackerd/venv/bin/trackerd is pip's console script for [project.scripts]; its Python
dependencies (NumPy, OpenCV, ...) are left out, which keeps this to seconds and leaves a daemon that
could not run. `verify` checks that ExecStart is executable, not that it runs.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

from tests.wheel import build_wheel

REPO = Path(__file__).resolve().parents[2]
INSTALL = REPO / "scripts" / "install"
UNITS = ("trackerd.service", "trackerd-cpu-latency.service")
ENTRY_POINT = "opt/trackerd/venv/bin/trackerd"

pytestmark = [pytest.mark.root, pytest.mark.slow]


def _missing() -> str | None:
    if os.geteuid() != 0:
        return "needs root (scripts/install chowns to the trackerd group; verify runs in a mount namespace)"
    for tool in ("systemd-analyze", "systemd-sysusers", "unshare"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed"
    if not Path("/bin").is_symlink():
        return "lending the host's OS to the root below expects a merged /usr (/bin -> usr/bin)"
    return None


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """trackerd's wheel, built offline (scripts/install builds the checkout with pip's isolated build,
    which takes setuptools from an index: a test reaches nothing beyond loopback)."""
    return build_wheel(tmp_path_factory.mktemp("wheel"))


def _install(root: Path, wheel: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(INSTALL), "--root", str(root), "--no-deps", "--wheel", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.fixture(scope="module")
def root(tmp_path_factory: pytest.TempPathFactory, wheel: Path) -> Path:
    reason = _missing()
    if reason:
        pytest.skip(reason)
    root = tmp_path_factory.mktemp("root")
    result = _install(root, wheel)
    assert result.returncode == 0, result.stdout + result.stderr
    return root


def _verify(root: Path, *units: str, hide_entry_point: bool = False) -> subprocess.CompletedProcess[str]:
    """`systemd-analyze verify --root=ROOT` on units installed in ROOT.

    ROOT holds only what scripts/install put there, but verify also loads the system's own units
    (sysinit.target, network-online.target) and checks ExecReload's /bin/kill, as it would in a
    whole OS image. So the host's /usr is lent to ROOT read-only, in a private mount namespace that
    ends with the command; /etc and /opt stay ROOT's own.
    """
    (root / "usr").mkdir(exist_ok=True)
    for name in ("bin", "lib", "lib64", "sbin"):
        host = Path("/") / name
        if host.is_symlink() and not (root / name).is_symlink():
            (root / name).symlink_to(os.readlink(host))
    hide = f'mount -t tmpfs tmpfs "$root/{Path(ENTRY_POINT).parent}"' if hide_entry_point else ":"
    script = f"""set -eu
root=$1; shift
mount --bind /usr "$root/usr"
mount -o remount,bind,ro "$root/usr"
{hide}
exec systemd-analyze verify --root="$root" "$@"
"""
    paths = [f"/etc/systemd/system/{unit}" for unit in units]
    return subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "sh", "-c", script, "sh", str(root), *paths],
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.parametrize("unit", UNITS)
def test_installed_unit_passes_systemd_analyze_verify(root: Path, unit: str):
    result = _verify(root, unit)
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "", result.stderr


def test_verify_looks_at_the_installed_entry_point(root: Path):
    """The check above is the root's: without the venv's bin/ (hidden in the namespace), it fails."""
    result = _verify(root, "trackerd.service", hide_entry_point=True)
    assert result.returncode != 0
    assert f"/{ENTRY_POINT} is not executable" in result.stderr, result.stderr


def test_install_puts_everything_where_the_docs_say(root: Path):
    entry_point = root / ENTRY_POINT
    assert entry_point.stat().st_mode & stat.S_IXOTH
    # pip's console script for [project.scripts] trackerd = "trackerd.cli.main:main", not a stand-in.
    assert "from trackerd.cli.main import main" in entry_point.read_text()
    assert "include-system-site-packages = true" in (root / "opt/trackerd/venv/pyvenv.cfg").read_text()

    passwd = {line.split(":")[0]: line.split(":") for line in (root / "etc/passwd").read_text().splitlines()}
    assert passwd["trackerd"][6] == "/usr/sbin/nologin"
    gid = int(passwd["trackerd"][3])
    etc = (root / "etc/trackerd").stat()
    assert (stat.S_IMODE(etc.st_mode), etc.st_uid, etc.st_gid) == (0o750, 0, gid)
    rig = (root / "etc/trackerd/rig.toml").stat()
    assert (stat.S_IMODE(rig.st_mode), rig.st_uid, rig.st_gid) == (0o640, 0, gid)

    for unit in UNITS:
        installed = root / "etc/systemd/system" / unit
        assert installed.read_text() == (REPO / "systemd" / unit).read_text()
        # Documentation= names the docs the install copied.
        docs = [
            line.split("=", 1)[1] for line in installed.read_text().splitlines() if line.startswith("Documentation=")
        ]
        assert docs, unit
        for url in docs:
            assert url.startswith("file:///"), url
            assert (root / url.removeprefix("file:///")).is_file(), url


def test_reinstall_keeps_the_operators_files(root: Path, wheel: Path):
    rig = root / "etc/trackerd/rig.toml"
    shipped = rig.read_text()
    drop_in = root / "etc/systemd/system/trackerd.service.d/site.conf"
    try:
        rig.write_text(shipped + "# edited for this room\n")
        drop_in.parent.mkdir()
        drop_in.write_text("[Service]\nEnvironment=SITE=1\n")
        result = _install(root, wheel)
        assert result.returncode == 0, result.stdout + result.stderr
        assert rig.read_text().endswith("# edited for this room\n")
        assert drop_in.read_text() == "[Service]\nEnvironment=SITE=1\n"
        assert (root / ENTRY_POINT).is_file()
    finally:
        rig.write_text(shipped)
        shutil.rmtree(drop_in.parent, ignore_errors=True)
