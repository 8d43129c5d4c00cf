"""The live view's path-mode accumulation: films of 16 samples that continue one low-discrepancy
sequence (`Film.first_sample`, what `raylume view` does) against films that each begin a
sequence of a new seed (what it did before), both through the `Film` / `Session.add_samples`
API the view uses. For k films: the mean squared error of the pooled image against a reference
(the mean of two 4096-spp renders of other seeds), averaged over --seeds starting seeds, and the
ratio before / now. The peer is the view's own earlier rule; no other renderer has this view.

    python benchmarks/bench_view_films.py [--scene examples/cornell.toml] [--size 64] [--films 1 4 10 32]
                                          [--seeds 4] [--threads N]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import REPO, machine, run_main, table

FILM_SPP = 16  # the view's films (viewer/renderer.py's PATH_FILM_SPP)


def pooled(session, size: int, films: int, seed: int, one_sequence: bool, threads: int | None) -> np.ndarray:
    """The image of `films` films of FILM_SPP samples, their sums pooled: one sequence
    (first_sample after first_sample) or a new seed a film."""
    import raylume
    from raylume.kernels.film.film import sums_image

    sums = None
    for k in range(films):
        first = FILM_SPP * k if one_sequence else 0
        film = raylume.Film(size, size, "box", total_spp=FILM_SPP, first_sample=first)
        session.add_samples(film, FILM_SPP, seed=seed if one_sequence else seed + k, threads=threads)
        sums = film.sums.copy() if sums is None else sums + film.sums
    return sums_image(sums, None, films * FILM_SPP).astype(np.float64)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default=str(REPO / "examples" / "cornell.toml"))
    parser.add_argument("--size", type=int, default=64, help="image side")
    parser.add_argument("--films", type=int, nargs="+", default=[1, 4, 10, 32])
    parser.add_argument("--seeds", type=int, default=4, help="starting seeds averaged over")
    parser.add_argument("--threads", type=int, default=None)
    args = parser.parse_args()

    import raylume

    print(f"{machine()}\n")
    scene = raylume.load_scene(args.scene).with_render(
        width=args.size, height=args.size, mode="path", filter="box", texture_filter=False
    )
    session = raylume.Session(scene)
    renders = [session.render(spp=4096, seed=s, threads=args.threads, aovs=False) for s in (90001, 90002)]
    reference = sum(image.rgb.astype(np.float64) for image in renders) / 2
    rows = []
    for films in args.films:
        before, now = [], []
        for t in range(args.seeds):
            seed = 100 * (t + 1)
            before.append(np.mean((pooled(session, args.size, films, seed, False, args.threads) - reference) ** 2))
            now.append(np.mean((pooled(session, args.size, films, seed, True, args.threads) - reference) ** 2))
        b, n = float(np.mean(before)), float(np.mean(now))
        rows.append([films, films * FILM_SPP, f"{b:.3g}", f"{n:.3g}", f"{b / n:.2f}x"])
    print(f"{args.scene} at {args.size} x {args.size}, path mode, films of {FILM_SPP} spp, {args.seeds} seeds\n")
    headers = ["films", "spp", "MSE: a new seed a film", "MSE: one sequence", "before / now"]
    print(table(headers, rows))


if __name__ == "__main__":
    run_main(main)
