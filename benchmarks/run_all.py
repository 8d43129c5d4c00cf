"""Run the benchmarks in turn (each prints its own markdown table, and its wall time after it).

python benchmarks/run_all.py [--quick]

--quick runs every script in benchmarks/ once, with small images, meshes, spp and repeats: a
smoke run that each script still works (about 4 minutes on 2 cores, none over a minute; the
timings are too small to quote). Without it, the figures: the main benchmarks as the README's
tables were made (bench_bvh.py and bench_path.py redraw their plots in docs/images,
bench_scaling.py its own), then the others with their default arguments (a few minutes each at
most): the full run takes half an hour or more.

Three are in the quick run only: bench_compile.py (its defaults, 3 cold compiles of 8 kinds of
work in new processes, take over ten minutes), bench_builds.py and ab_queries.py (they compare
checkouts, `--src OLD --src NEW` and `--a OLD --b NEW`; the quick run gives them this one
twice). Mitsuba's scripts run their timing commands (mitsuba_reference.py timing,
mitsuba_media.py bench, mitsuba_scene.py compare), never `reference`, which rewrites the stored
references in tests/reference.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def benchmarks(quick: bool) -> list[list[str]]:
    """Each script's command line, in the order they run."""
    commands = [
        ["bench_seed.py"] + (["--python-size", "200"] if quick else []),
        ["bench_glass.py"],
        ["bench_spp.py"],
        ["bench_bvh.py"]
        + (["--quick", "--size", "512"] if quick else ["--plot", str(HERE.parent / "docs/images/bvh_scaling.png")]),
        ["bench_hits.py"] + (["stanford-bunny", "10k", "1M", "--size", "512"] if quick else []),
        ["bench_shadows.py"] + (["stanford-bunny", "10k", "1M", "--size", "512"] if quick else []),
        ["bench_growth.py"] + (["10k", "100k", "--size", "256", "--rounds", "3"] if quick else []),
        ["bench_load.py"] + (["100k", "--size", "256", "--repeats", "1"] if quick else []),
        ["bench_scaling.py"] + (["--quick"] if quick else []),
        ["bench_path.py"] + (["--quick"] if quick else ["--plot", str(HERE.parent / "docs/images/path_rmse.png")]),
        ["bench_bdpt.py"] + (["--size", "32x18", "--reference-spp", "64", "--rounds", "1"] if quick else []),
        ["bench_adaptive.py"]
        + (["--size", "32", "--spp", "128", "--thresholds", "0.1", "--rounds", "1"] if quick else []),
        ["bench_first_run.py"] + (["--repeats", "1"] if quick else []),
        ["bench_cluster.py"] + (["--quick"] if quick else []),
        ["bench_instances.py"]
        + (
            ["--width", "256", "--height", "192", "--repeats", "1", "--counts", "1,10,100", "--flat-max", "10"]
            if quick
            else []
        ),
        ["bench_view.py"] + (["--sizes", "160x120", "--seconds", "1", "--runs", "1"] if quick else []),
        ["bench_view_films.py"] + (["--size", "16", "--films", "1", "4", "--seeds", "1"] if quick else []),
        ["cache_misses.py"] + (["--size", "256", "40k", "1M"] if quick else []),
        ["count_instructions.py"] + (["--size", "128", "10k"] if quick else []),
        ["probe_wavefront_path.py"] + (["--size", "64", "--spp", "2", "--rounds", "1"] if quick else []),
        ["mitsuba_reference.py", "timing"] + (["--spp", "16", "--repeats", "1"] if quick else []),
        ["mitsuba_media.py", "bench"] + (["--rounds", "1", "--size", "32", "--spp", "4"] if quick else []),
        ["mitsuba_scene.py", "compare"] + (["--width", "64", "--height", "32", "--spp", "4"] if quick else []),
    ]
    if quick:  # in the quick run only (see above)
        commands += [
            ["bench_compile.py", "--repeats", "1", "intersect", "seed"],
            ["bench_builds.py", "--src", str(HERE.parent), "--rounds", "1", "seed", "hits"],
            ["ab_queries.py", "--a", str(HERE.parent), "--b", str(HERE.parent), "--rounds", "2", "10k"],
        ]
    return commands


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--quick", action="store_true", help="every script once, small and fast: a smoke run (about 4 minutes)"
    )
    quick = parser.parse_args().quick
    for args in benchmarks(quick):
        print(f"\n## {args[0]}\n", flush=True)
        started = time.perf_counter()
        subprocess.run([sys.executable, str(HERE / args[0]), *args[1:]], check=True)
        print(f"\n({' '.join(args)}: {time.perf_counter() - started:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
