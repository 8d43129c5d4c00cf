"""Run every benchmark in turn (each prints its own markdown table). Takes several minutes.

python benchmarks/run_all.py [--quick]
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
QUICK = "--quick" in sys.argv

BENCHMARKS = [
    ["bench_seed.py"] + (["--python-size", "200"] if QUICK else []),
    ["bench_glass.py"],
    ["bench_spp.py"],
    ["bench_bvh.py"]
    + (["--quick", "--size", "512"] if QUICK else ["--plot", str(HERE.parent / "docs/images/bvh_scaling.png")]),
    ["bench_hits.py"] + (["stanford-bunny", "10k", "1M", "--size", "512"] if QUICK else []),
    ["bench_shadows.py"] + (["stanford-bunny", "10k", "1M", "--size", "512"] if QUICK else []),
    ["bench_scaling.py"] + (["--quick"] if QUICK else []),
    ["bench_path.py"] + (["--quick"] if QUICK else ["--plot", str(HERE.parent / "docs/images/path_rmse.png")]),
]

for args in BENCHMARKS:
    print(f"\n## {args[0]}\n", flush=True)
    subprocess.run([sys.executable, str(HERE / args[0]), *args[1:]], check=True)
