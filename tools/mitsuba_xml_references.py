"""Render the XML scenes of tests/reference/mitsuba_xml_scenes.py with Mitsuba 3 (scalar_rgb) and
keep, for each, what tests/test_mitsuba_vs_reference.py compares raylume against: the mean image
over K seeds and each seed's 8 x 8-block means and image mean, in
tests/reference/mitsuba_xml/NAME.npz, with the scene's digest (the test refuses a stale reference).

    python tools/mitsuba_xml_references.py [NAME ...] [--seeds 16] [--spp 256]

Mitsuba loads the very XML files the test gives raylume (written into a temporary folder).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from reference.mitsuba_xml_scenes import SCENES, SIZE, write_scene  # noqa: E402

OUT = ROOT / "tests" / "reference" / "mitsuba_xml"
BLOCK = 8


def block_means(images: np.ndarray) -> np.ndarray:
    s, h, w, c = images.shape
    return images.reshape(s, h // BLOCK, BLOCK, w // BLOCK, BLOCK, c).mean(axis=(2, 4))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=list(SCENES))
    parser.add_argument("--seeds", type=int, default=16)
    parser.add_argument("--spp", type=int, default=256)
    args = parser.parse_args(argv)

    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    OUT.mkdir(parents=True, exist_ok=True)
    for name in args.names:
        with tempfile.TemporaryDirectory() as tmp:
            path, digest = write_scene(name, Path(tmp))
            scene = mi.load_file(str(path))
            start = time.perf_counter()
            images = np.stack(
                [
                    np.array(mi.render(scene, seed=s, spp=args.spp), dtype=np.float64)[:, :, :3]
                    for s in range(args.seeds)
                ]
            )
        seconds = time.perf_counter() - start
        assert images.shape[1:3] == (SIZE, SIZE)
        meta = {
            "scene": name,
            "scene_digest": digest,
            "width": SIZE,
            "height": SIZE,
            "block": BLOCK,
            "seeds": args.seeds,
            "spp_per_seed": args.spp,
            "variant": "scalar_rgb",
            "mitsuba_version": mi.__version__,
            "render_seconds": round(seconds, 1),
            "date": time.strftime("%Y-%m-%d"),
        }
        np.savez_compressed(
            OUT / f"{name}.npz",
            mean=images.mean(axis=0).astype(np.float32),
            seed_block_means=block_means(images).astype(np.float32),
            seed_global_means=images.mean(axis=(1, 2)).astype(np.float32),
            meta=np.array(json.dumps(meta)),
        )
        print(f"{name}: {seconds:.1f} s, image mean {images.mean(axis=(0, 1, 2)).round(4)}", flush=True)


if __name__ == "__main__":
    main()
