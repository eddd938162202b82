"""Rendered frames stay bit for bit what they were (trackerd/sim): a guard for refactoring the renderer.

Each scene below is rendered exactly as its user renders it (the demo's loop frames as
:func:`trackerd.sim.loops.render_loop`'s workers do, randomized installations and shots as
``trackerd bench robustness`` does, a hand as the interaction bench does) and its image and
ground truth are hashed. The hashes were recorded on the code before the simulator was split
into modules (issue 16); a change that moves code without changing what it computes keeps them.
They hold for one set of OpenBLAS matrix kernels (the last bit of a product differs between
kernels): tests/conftest.py asks for the "Haswell" ones, which every AVX2 CPU runs; the hashes
were recorded again with those on 2026-12-04, at 9560820 (the first ones were of the "SkylakeX"
kernels an Intel CPU chose by itself); without AVX2 the module is skipped. On 2026-12-05 the
lens maps became exact (trackerd/sim/lens_rays.py; RENDER_VERSION 2): the 11 frames of
distorted cameras whose images that moved were recorded again (the demo rig's map moved by
at most 1.3e-6 px, and only its background's bits changed).
A change meant to alter the images (and bumping RENDER_VERSION) records them again: run this
module as a script to print them, with the kernels the tests use:
``OPENBLAS_CORETYPE=Haswell OPENBLAS_NUM_THREADS=1 .venv/bin/python tests/sim/test_rendered_bits.py``.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from trackerd.config.loader import load_rig
from trackerd.config.models import RigConfig

if TYPE_CHECKING:
    from trackerd.sim.render import SceneRenderer

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(
    os.environ.get("OPENBLAS_CORETYPE") != "Haswell",
    reason="the hashes are of OpenBLAS's Haswell kernels, which tests/conftest.py asks for only on a CPU with AVX2",
)

EXPECTED = {
    "demo figure8 frame 0 camera 0": "79f5170a660e73e0b39255477632da2854733773c52e54d445abcbe1c136c964",
    "demo figure8 frame 0 camera 1": "c8528f4204577170d894a02734628021b8b4e157d837851bb79839581c4e353c",
    "demo figure8 frame 37 camera 0": "8bf1946243c2fcb38490e2b6396ca835c5739646f0e9f3347323b516edc6e5dc",
    "demo figure8 frame 37 camera 1": "1bf5f038ac0cfd3679e8695a1ab08586f1a705a40bbc84e67eae7c2da3a17562",
    "demo figure8 frame 81 camera 0": "a71748069eafc5ed8d2290814b5fb11c7b4e4bbf5c5f3a2c548126e47d4e6132",
    "demo figure8 frame 81 camera 1": "242b8d9f5a319c7b834fce4e5490949bccd3916defc3a8e0e68d1ee1ab346e0d",
    "demo background camera 1": "a9f4df1b8689e96935be5962adf08a0f1adc1008905d7796a51e064217c3e536",
    "hand three fingers": "6b06836ade13bd8e64e9dbda2f8bc14e8b5b3e316d715f0e5ca7172a193c7a5d",
    "hand empty room": "192c368e8180602dc68e479dc9e69f061cf30ab9259c7bb56ff84c640d2c3ba6",
    "random 0 shot 0 camera 0": "ee5d10dcd4a8c99858fa0798f947e16b85f46ec268b3f90af18e48dec5aa5e83",
    "random 0 shot 0 camera 1": "b94de5e680f57f418de26bfdf10de10322f6725945a6c75c85f86f3bf4ab3f65",
    "random 0 shot 0 camera 2": "34a01157ff59f2d6fe9a170825e00d8832987568eca3e5615d514a045ad8fc80",
    "random 0 shot 1 camera 0": "dcb56b137b5af8b752515a5a14b0e4788c4f9c2534ff705fc290c724b07ea221",
    "random 0 shot 1 camera 1": "6df3a48b17666abaf514bdafd5adabfcaad5dbbc44065dd41fdd25c3c49edec9",
    "random 0 shot 1 camera 2": "f346f5ff740bf7bd997b0340546bb4e239e715117351d31416cefa251f8fe2b6",
    "random 0 shot 2 camera 0": "139ad5f95f37f9dbc5534d32ad0eaf0f6dc457bef160d056d4d9e5751876fd92",
    "random 0 shot 2 camera 1": "1602f234158b79d0f42b6d3a178ad5c3cf93d0592abb364dfc6f771e08297715",
    "random 0 shot 2 camera 2": "30b73a83f982a710e7d01185ece92b1cb1bf420b1181c2120b3172bdf0c90779",
    "random 2 shot 0 camera 0": "f17d648ed249a5a3c579b6a20bdcb0e791ffba7da635d823c67d50e0e769f34e",
    "random 2 shot 0 camera 1": "07c644973e8f5f80bc6ae20f2ffbeb3d164a85ddd18e7a3eea6c5fe97b4b6b0f",
    "random 2 shot 1 camera 0": "d3d2c0bad43f10fbc6e839f507315c06123593d922c7c96694c04df4b7615650",
    "random 2 shot 1 camera 1": "aacc71173c4943f5bbdc15575023bad3a1da5bf1aee87430df03e0a5c2aebfa4",
    "random 2 shot 2 camera 0": "d576f9844b08318bde7f395aa5b8a77deb76dad5b5f015bd5ed2d18429cd1e57",
    "random 2 shot 2 camera 1": "15f56da259407955e862757bedb9402cb1f969b233a3942c5eee3cb580e10eb1",
    "random 3 shot 0 camera 0": "6ccd756e03b48572df4c3776c93b5901ecec489c60858b77507ba527eba19d5d",
    "random 3 shot 0 camera 1": "afd38fc76de53960e9be904c66845fb9262203076b8dfa83b40c8a248c01d2da",
    "random 3 shot 1 camera 0": "9ae68b9faf970092c4edb779fcd98f2081fc5431f07a464b367c29fc8b430525",
    "random 3 shot 1 camera 1": "a2ea55a0378f517c3e1b3863aa9bd1d76058402190a163fed20d5528bb009181",
    "random 3 shot 2 camera 0": "b6e2eae60fd53883ed181aa58bfa6921bc381b91d897c2b486f0f730e803ebf0",
    "random 3 shot 2 camera 1": "46135864bada912d107c91f326040680750d2a91662db1a62597d02dad9bf6fd",
    "random 4 shot 0 camera 0": "5c1ac37ffdf426ec2159b5fbe228878a7b3674b36ba8043534f77dee8165b5e7",
    "random 4 shot 0 camera 1": "a639cc1b5797fabe814bc6ef0305213cfa2e0292feabb22a222b1bfa55232f67",
    "random 4 shot 1 camera 0": "78eb9ca07dd437820f50c526319fd361dca3d075596cd28c2d589c6c2699f878",
    "random 4 shot 1 camera 1": "6e53b1e0feb59d3d63ba044f82c416cfcca96b6cd474f958d67977e7b4e4dd3e",
    "random 4 shot 2 camera 0": "5dfb789910bcf72aba489970e2fafa50bdcb7d4b891a791c195159642685b40d",
    "random 4 shot 2 camera 1": "3561ad84a400ff24d62a86b770ba70b24dfc4159e5445f9aacf1502cdd56dbcc",
    "random 7 shot 0 camera 0": "4e824c3d3712f9c0b9d22a4802b596a75276150a3822179a466790bac882c4e3",
    "random 7 shot 0 camera 1": "a73a33680489fdcf41bd541fd9c5c3676e159c70595423e1bc654e293239978f",
    "random 7 shot 1 camera 0": "2c473129ebeb88be0438e659439db3d8ce9c5f243c046f6b5b570c22d843ec20",
    "random 7 shot 1 camera 1": "281b9d77dde33bdd3bb7ce9af528d89cd91b2d69d02a52d3b013c0db851a2e8c",
    "random 7 shot 2 camera 0": "299468828d0c5c853ba0dbf18eee210eaa255d2dc59f49b261cca1ef153f94ed",
    "random 7 shot 2 camera 1": "8339f1e2f6c80319c958810082ed59e0f33687a42bbd57e22831a4d7cc2e8109",
    "random 8 shot 0 camera 0": "0450d5d8eeab2bcbfce87ccd94d0f5f983ba1b15d17ec6c43dad2eed187d1efa",
    "random 8 shot 0 camera 1": "f12e880c1198de766aec107847cad071d027a3daacf76d3e2c84bce56f6e8e6a",
    "random 8 shot 1 camera 0": "76c0ed80065c0a63add3b44f88db26b47f513efcf6635751a4853ba798c6deb0",
    "random 8 shot 1 camera 1": "24d7d17be55913ec06c9217c9640b5bc28b8124ebbd836131de8b0008974e657",
    "random 8 shot 2 camera 0": "52b597bd041fe80db383f97a0e1a487fb6e491f02069d5f86ce7389dbc293901",
    "random 8 shot 2 camera 1": "b5b3196e243d8b96e48922af2c31ebd0f13642b6e92d071294c7042e7160d9f8",
}
"""Scene name -> sha256 of its frames and truth (OpenBLAS's Haswell kernels; see the module's docstring)."""


def _digest(*parts: object) -> str:
    """sha256 over arrays' shapes, dtypes and bytes and other values' repr."""
    digest = hashlib.sha256()
    for part in parts:
        if isinstance(part, np.ndarray):
            digest.update(repr((part.shape, part.dtype.str)).encode())
            digest.update(np.ascontiguousarray(part).tobytes())
        else:
            digest.update(repr(part).encode())
    return digest.hexdigest()


def _view_parts(view) -> list[object]:  # a RenderedView
    truth = view.truth
    parts: list[object] = [view.image, view.pixel_format]
    for colour in ("red", "blue"):
        parts += [truth.centre_px[colour], truth.centroid_px[colour], truth.area_px[colour], truth.full_area_px[colour]]
    return parts


def _demo_scenes(cache_dir: Path, renderer: SceneRenderer | None = None) -> Iterator[tuple[str, str]]:
    """Frames of the demo's loop (config/simulated.toml, figure8), rendered as a loop worker renders them
    (by ``renderer`` if given, else by a new one caching its rooms in ``cache_dir``)."""
    from trackerd.sim.motion import DEFAULT_PERIOD_S, make_motion
    from trackerd.sim.render import SceneRenderer

    rig: RigConfig = load_rig(REPO / "config" / "simulated.toml").config
    if renderer is None:
        renderer = SceneRenderer(rig, cache_dir=cache_dir)
    moving = make_motion("figure8", rig, DEFAULT_PERIOD_S)
    content_fps = 30.0
    for index in (0, 37, 81):
        for camera in range(len(rig.cameras)):
            rng = np.random.default_rng([rig.simulation.seed, camera, index])
            view = renderer.render(camera, moving(index / content_fps), rng)
            yield f"demo figure8 frame {index} camera {camera}", _digest(*_view_parts(view))
    # The empty room and the noiseless background, which the hand and the board renderers start from.
    yield "demo background camera 1", _digest(renderer.background_rgb(1))


def _hand_scene(cache_dir: Path) -> Iterator[tuple[str, str]]:
    from trackerd.sim.hand import HandRenderer, random_hand_pose
    from trackerd.sim.render import SceneRenderer

    rig: RigConfig = load_rig(REPO / "config" / "simulated.toml").config
    hands = HandRenderer(SceneRenderer(rig, cache_dir=cache_dir), 0)
    rng = np.random.default_rng(16)
    pose = random_hand_pose(3, rng, hands.camera.width_px, hands.camera.height_px)
    shown = hands.render(pose, rng)
    yield "hand three fingers", _digest(shown.image, shown.palm_px, shown.box_px, shown.area_px)
    yield "hand empty room", _digest(hands.empty(rng))


RANDOMIZED_SEEDS = (0, 2, 3, 4, 7, 8)
"""Installations drawn with np.random.default_rng([16, seed]): ceiling/dim/3 cameras, behind high,
close/uneven, ceiling/glossy, behind high/4K (background every 2nd pixel), behind high/spotlight.
Their three shots each cover every display content, strong and some blur, a hand and a body in front."""


def _randomized_scenes(seed: int, shots: int = 3) -> Iterator[tuple[str, str]]:
    """Shots of a randomized installation, rendered as `trackerd bench robustness` renders them."""
    from trackerd.sim.appearance import wall_content
    from trackerd.sim.randomized import random_rig, random_shot
    from trackerd.sim.render import SceneRenderer

    rng = np.random.default_rng([16, seed])
    drawn = random_rig(rng, name=f"bits-{seed}")
    widest = max(c.width_px for c in drawn.cameras)
    # Odd seeds as the bench renders (a noise field per camera), even ones with fresh noise per frame.
    renderer = SceneRenderer(
        drawn.rig,
        list(drawn.cameras),
        look=drawn.look,
        cache_dir=False,
        background_step=1 if widest <= 2000 else 2,
        noise_field=seed % 2 == 1,
    )
    for frame in range(shots):
        shot = random_shot(drawn, rng)
        content = wall_content(shot.content_kind, rng)
        for camera in range(len(drawn.cameras)):
            view = renderer.render(
                camera,
                shot.pose,
                rng,
                motion_to=shot.motion_to,
                motion_steps=shot.motion_steps,
                occluders=shot.occluders,
                content=content,
            )
            name = f"random {seed} shot {frame} camera {camera}"
            yield name, _digest(*_view_parts(view))


def all_scenes(cache_dir: Path) -> dict[str, str]:
    found = dict(_demo_scenes(cache_dir))
    found.update(_hand_scene(cache_dir))
    for seed in RANDOMIZED_SEEDS:
        found.update(_randomized_scenes(seed))
    return found


@dataclass(frozen=True)
class FreshRooms:
    """A renderer that rendered both cameras' rooms afresh, and the cache folder it wrote them to."""

    renderer: SceneRenderer
    folder: Path
    files_after_each: list[int]
    """How many cached rooms the folder held after each camera's room was rendered, in camera order."""


@pytest.fixture(scope="module")
def fresh_rooms(tmp_path_factory: pytest.TempPathFactory) -> FreshRooms:
    """Rendering a room takes seconds (each camera's, 6 s of CPU here): the module's two tests that need
    them rendered afresh share one rendering, the demo's frames hashed from the renderer that made them,
    the cache read back by a second renderer (when they run in one process: under xdist's default
    distribution two adjacent tests mostly do)."""
    from trackerd.sim.render import SceneRenderer

    folder = tmp_path_factory.mktemp("rooms")
    rig: RigConfig = load_rig(REPO / "config" / "simulated.toml").config
    renderer = SceneRenderer(rig, cache_dir=folder)
    counts = []
    for camera in range(len(rig.cameras)):
        renderer.background_rgb(camera)
        counts.append(len(list(folder.glob("bg-*.npy"))))
    return FreshRooms(renderer, folder, counts)


def test_the_demo_and_hand_frames_are_bit_identical(fresh_rooms: FreshRooms) -> None:
    found = dict(_demo_scenes(fresh_rooms.folder, fresh_rooms.renderer))
    found.update(_hand_scene(fresh_rooms.folder))
    expected = {name: digest for name, digest in EXPECTED.items() if name.startswith(("demo", "hand"))}
    assert found == expected


def test_a_background_read_from_the_cache_gives_the_same_frames(fresh_rooms: FreshRooms) -> None:
    """A second renderer reads the room the first rendered and wrote to disk: the same frame."""
    from trackerd.sim.motion import DEFAULT_PERIOD_S, make_motion
    from trackerd.sim.render import SceneRenderer

    rig: RigConfig = load_rig(REPO / "config" / "simulated.toml").config
    assert fresh_rooms.files_after_each == [1, 2]  # one file per camera's room, written as it was rendered
    renderer = SceneRenderer(rig, cache_dir=fresh_rooms.folder)
    pose = make_motion("figure8", rig, DEFAULT_PERIOD_S)(37 / 30.0)
    view = renderer.render(0, pose, np.random.default_rng([rig.simulation.seed, 0, 37]))
    assert _digest(*_view_parts(view)) == EXPECTED["demo figure8 frame 37 camera 0"]


@pytest.mark.parametrize("seed", RANDOMIZED_SEEDS)
def test_randomized_frames_are_bit_identical(seed: int) -> None:
    found = dict(_randomized_scenes(seed))
    expected = {name: digest for name, digest in EXPECTED.items() if name.startswith(f"random {seed} ")}
    assert found == expected


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as scratch:
        for name, digest in all_scenes(Path(scratch)).items():
            print(f"    {name!r}: {digest!r},")
