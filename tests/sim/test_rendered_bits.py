"""Rendered frames stay bit for bit what they were (trackerd/sim): a guard for refactoring the renderer.

Each scene below is rendered exactly as its user renders it (the demo's loop frames as
:func:`trackerd.sim.loops.render_loop`'s workers do, randomized installations and shots as
``trackerd bench robustness`` does, a hand as the interaction bench does) and its image and
ground truth are hashed. The hashes were recorded on the code before the simulator was split
into modules (issue 16); a change that moves code without changing what it computes keeps them.
A change meant to alter the images (and bumping RENDER_VERSION) records them again: run this
module as a script to print them.
"""

from __future__ import annotations

import hashlib
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

EXPECTED = {
    "demo figure8 frame 0 camera 0": "34006dd8f8b391dd1329daba0f86a89c2ab61b19a18286013169af8ecc6a2aec",
    "demo figure8 frame 0 camera 1": "a0cb1b624273a92df9dc5fe69ebe1dbc4cbda965fd4f33dc079420fe7b3e060f",
    "demo figure8 frame 37 camera 0": "5a190d2920aafb362478f16bbb20218c5a836db988edf444b2539225be245f30",
    "demo figure8 frame 37 camera 1": "dd720f34fb10a430064aa513fb43309fca56d43c305b45dae8a1d2cd04c76259",
    "demo figure8 frame 81 camera 0": "a71748069eafc5ed8d2290814b5fb11c7b4e4bbf5c5f3a2c548126e47d4e6132",
    "demo figure8 frame 81 camera 1": "7aa0a3c0f7fe91e5677e3c94979b0fe633073e1efb0c080eb1219741b515419d",
    "demo background camera 1": "39afa916847d93dd4e321c47ece60f24de76c80e2ae5f589cc93a457e4978e1f",
    "hand three fingers": "8415b52bd400cd492782c499e7672d55daa625325899bfe0e37751aa05cc95c7",
    "hand empty room": "192c368e8180602dc68e479dc9e69f061cf30ab9259c7bb56ff84c640d2c3ba6",
    "random 0 shot 0 camera 0": "50d84ff5485588048e54dfcd3ab08a0b87c44fc412a692538159dde09db71bc2",
    "random 0 shot 0 camera 1": "414876a4d7e770ca90cde07afec5094393ff426784fbcbae0a1099282fe1a7b9",
    "random 0 shot 0 camera 2": "3e493b503000b722aeb97c7ef19bb38bfeab9498e89de62f9ee4d2321153a312",
    "random 0 shot 1 camera 0": "487ebb55e80f2aee4387ace932b12be36b6d14cd2b58543f5331077059f6e139",
    "random 0 shot 1 camera 1": "30c6f723ba7498eba49cc740d3c633e6c1f721a41d00db5212eda13fb8ac21a0",
    "random 0 shot 1 camera 2": "f640162de027c4720cf2a6ec2135d6891d3fa91f18eac9be9b8287b787fe13e3",
    "random 0 shot 2 camera 0": "788850eb0ce80da1103d773c853f0783256d0c6de42dc833228baab9b302959b",
    "random 0 shot 2 camera 1": "d0432b31899b1769aaedeaf59655db1283b84a3d24172861265d0f48fa8bb06c",
    "random 0 shot 2 camera 2": "4c6b0bd51a9a9079b26cdefadea6c22fa0ba218b28748974259f61937f292969",
    "random 2 shot 0 camera 0": "94494f708a88e3c740d1ed479f054279f565d25fb4470b2877a6fd1e82f73987",
    "random 2 shot 0 camera 1": "bc571c4e1c54d19a1e30de9a40cb8974ecab732e27d2e1bae88ef0c0a09ef54f",
    "random 2 shot 1 camera 0": "6595687f4e64e0d4077cf3b419ea321d304de235885e89d4ce4fbbd93632535a",
    "random 2 shot 1 camera 1": "7622960454e6a59035c755a9327cb2af3679e5952e4fcabd1d031466bb69f1a8",
    "random 2 shot 2 camera 0": "7c39b2481d6c14e583e01106c7222a5d9331a69667612b91976dc8161faff93d",
    "random 2 shot 2 camera 1": "e03c23e7d54b6c8be1a4b182f382a3b781be0cfbcb80c22bd45d001d3d287320",
    "random 3 shot 0 camera 0": "7b3c4af420ae12c18027e44f211df67813126b0336b7873977b53d75724cd5cf",
    "random 3 shot 0 camera 1": "4b43ce594cb15ad391a89a3fd6cb4e4a5d9673ea879bb30cca0b687f4becc130",
    "random 3 shot 1 camera 0": "10259beb198d11b6c73156b024a7a6cf2ad98f63fc81de2b4d3f977c23243f74",
    "random 3 shot 1 camera 1": "677e214b3e57ed4025033e5503d00fded31901bcb6117264e5d1f0e91b0a7df6",
    "random 3 shot 2 camera 0": "a064b41f710c56e8872e0ad400a0afa33b8486cdfc28dac57d8d45757e809cac",
    "random 3 shot 2 camera 1": "3a4a8fb31d1d9b6c8c01a8daabbc5fea623e2f83975d66dc65e11d985aed79c0",
    "random 4 shot 0 camera 0": "8b587972082314ae4c01116cc7b90d8631e23c6aa9016f09ac1bb5a95f414798",
    "random 4 shot 0 camera 1": "4edf28f01862022fc6c83704c801e4bb4b9f9558e087bd6654a2a513744387db",
    "random 4 shot 1 camera 0": "1a18eff92e3400ac88861b1275bfdf022f2a251ca3a9897e5006d5d1d942bd7e",
    "random 4 shot 1 camera 1": "979fce1c1f67aece2ce655bd5966a36cc29e37bacdfc1507a849783aaf51ed57",
    "random 4 shot 2 camera 0": "e62468a95ddb4aa4e1d5aff18348f14294d354225edbd5a1f1f5d050e7add6f6",
    "random 4 shot 2 camera 1": "3854d5fe658f656dba9212ec627d440c075607448fd73f79250cfefa409b769f",
    "random 7 shot 0 camera 0": "a40e4296af5c7469603a869ffb0915690feda3cb36679ecd95caf7017ee67537",
    "random 7 shot 0 camera 1": "5f96e7077f59ba60558e39d8f238bd4fb4e7b52afc770c758cdd82ea882b6b54",
    "random 7 shot 1 camera 0": "0147669c4f2961150f1d46cb749ea03824a4fa793fc2db9c4dc99e130c48ceda",
    "random 7 shot 1 camera 1": "b264e9b5d8966a6b1b5c368abbee51ec2089bb8f23fe1c0346f674f0d1a9d7ac",
    "random 7 shot 2 camera 0": "1bf82f794214f9afbbfaac0936f5457419aed36a1d45d7a65d51a8b93894dfef",
    "random 7 shot 2 camera 1": "ca9bf051dc65f8bfa961a39810aa33d03e8669003ec4fec4664a6c09d787701c",
    "random 8 shot 0 camera 0": "4b605eaa89cf8219877830e4715baf552138a898eaf7ff2c1f522d967f923622",
    "random 8 shot 0 camera 1": "3b3bb16c6e1635e04a16b24640d4456b93fe78caed3f3ec440b9af6530c3225d",
    "random 8 shot 1 camera 0": "fc6c3d211ee9b95b0c8969870aad6c53204623eee83708e5296529d8e31b911f",
    "random 8 shot 1 camera 1": "f97299177800bbfd8d7ea91311532b929f84bd8c13a23eaa0d9fcfedc1aa5bb3",
    "random 8 shot 2 camera 0": "2cd144c9f518962dbe63fa9df8ee077974246d07e00c6271b888a313ae6bed07",
    "random 8 shot 2 camera 1": "eb9f18ae89c1778c6ce857f33829d4ba9cae169bd41dfd46e8dd85eec73f3427",
}
"""Scene name -> sha256 of its frames and truth, recorded on the renderer before the split."""


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
