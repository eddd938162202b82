"""Compression of recorded frames: ratio and CPU per 1080p frame for zstd, lz4 and zlib (docs/recording.md).

Frames: the rendered figure-eight loop of config/simulated.toml (BayerRG8 1920x1080, the simulator's
1 DN sensor noise), the same with 2 DN more Gaussian noise added, and the noiseless bundled test
recording. Each codec is measured on the frame itself and on its difference (mod 256) to the
previous frame of the same camera. One thread, CPU time (time.thread_time).

    .venv/bin/python scripts/bench_codecs.py [--frames 24]
"""

from __future__ import annotations

import argparse
import time
import zlib

import numpy as np


def codecs() -> dict:
    import zstandard

    out = {
        "zlib-1": (lambda b: zlib.compress(b, 1), zlib.decompress),
    }
    for level in (1, 3):
        c = zstandard.ZstdCompressor(level=level)
        d = zstandard.ZstdDecompressor()
        out[f"zstd-{level}"] = (c.compress, d.decompress)
    out["zstd--1 (fast)"] = (zstandard.ZstdCompressor(level=-1).compress, zstandard.ZstdDecompressor().decompress)
    try:
        import lz4.frame  # not a dependency of trackerd: measured when installed (pip install lz4)
    except ImportError:
        print("(lz4 not installed: pip install lz4 to measure it too)")
    else:
        out["lz4"] = (lambda b: lz4.frame.compress(b, compression_level=0), lz4.frame.decompress)
    return out


def frames_of(kind: str, n: int) -> list[np.ndarray]:
    if kind == "clean":
        from trackerd.recording.reader import Recording

        with Recording.open("tests/data/recording/figure8-leave.trec") as rec:
            return [np.array(rec.images(i)[0]) for i in range(min(n, len(rec)))]
    from trackerd.config.examples import example_rig
    from trackerd.config.loader import load_rig
    from trackerd.sim.rig import render_loop

    rig = load_rig(example_rig("simulated")).config
    loop = render_loop(rig, "figure8")
    cam0 = np.load(loop.frame_paths[0], mmap_mode="r")
    out = [np.array(cam0[i]) for i in range(min(n, loop.n_frames))]
    if kind == "noisy":
        rng = np.random.default_rng(1)
        out = [np.clip(f + rng.normal(0, 2.0, f.shape), 0, 255).astype(np.uint8) for f in out]
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=24)
    args = parser.parse_args()
    table = codecs()
    print(f"{'frames':<26}{'codec':<16}{'on':<7}{'ratio':>7}{'compress ms':>13}{'decompress ms':>15}")
    for kind, label in (("clean", "clean (no noise)"), ("sim", "simulator (1 DN)"), ("noisy", "noisy (1 DN + 2 DN)")):
        frames = frames_of(kind, args.frames)
        raw = sum(f.nbytes for f in frames)
        for name, (comp, decomp) in table.items():
            for on in ("frame", "delta"):
                inputs = [frames[0]] + [frames[i] - frames[i - 1] for i in range(1, len(frames))] if on == "delta" \
                    else frames
                t0 = time.thread_time()
                packed = [comp(x.tobytes()) for x in inputs]
                t1 = time.thread_time()
                for p in packed:
                    decomp(p)
                t2 = time.thread_time()
                stored = sum(len(p) for p in packed)
                print(f"{label:<26}{name:<16}{on:<7}{raw / stored:>7.2f}{1e3 * (t1 - t0) / len(frames):>13.1f}"
                      f"{1e3 * (t2 - t1) / len(frames):>15.1f}")


if __name__ == "__main__":
    main()
