"""Where a render's kernel time goes, by source line: `perf` samples of the compiled kernels,
named through the DWARF line tables of Numba's own object code.

    python tools/profile_kernels.py SCENE [--mode path] [--width 128] [--height 128] [--spp 16]
                                    [--seconds 8] [--top 25] [--aovs] [--instructions N]
    python tools/profile_kernels.py --hits MESH [--shadows] [--singly] [--width 1024] [--seconds 8]
                                    [--top 25] [--instructions N]
    python tools/profile_kernels.py (SCENE | --hits MESH [--shadows] [--singly]) --count [--calls 1] ...

Renders SCENE (a scene file or built-in name) again and again on 1 thread for --seconds while
`perf record -e cpu-clock` samples the process, then prints the share of the samples on each
source line the kernels' machine code came from (the innermost: the line whose code ran) and on
each function, counting every function inlined into the sampled code (so a helper's share holds
its callees'). Explicit-IR intrinsics (the box and triangle tests, the sweep's mask) are counted
at the line that calls them. The function shares are lower bounds: code that Numba inlines
itself (`inline="always"`, raylume's `inline_function`) keeps its own lines but not the chain
of callers LLVM's inlining records, so only the line table sees it whole.

The kernels are compiled with line tables (NUMBA_DEBUGINFO=1, less the `noinline`, bounds
checks and kept variables Numba's debug info adds: _line_tables_only; renders then take ~1.1x
their usual time, not ~2x) into a cache of their own (raylume-profile-lines, under
$NUMBA_CACHE_DIR or ~/.cache; an older raylume-profile beside it, the full debug build's, can
be deleted), so the first run compiles them (minutes, for path mode) and leaves the usual cache
alone; later runs load them from it. Renders leave out the AOV pass unless --aovs says. The
object code each kernel was loaded from is kept as it is read from the cache; a sample's address
less the kernel's entry is an offset into the object's code section, and `addr2line -i` gives
the inlined frames at it.

`--count` counts instead of sampling: the kernels run once (`--calls` times) under valgrind's
callgrind, which counts every instruction they execute and simulates their branches' prediction
(a counter per branch, no history: a pessimistic model), and the counts are reported per source
line and function, and per ray for --hits. Exact and repeatable where samples of a VM whose
speed drifts are not, so two versions' instructions can be compared to the last one (what an
instruction costs is another matter). Under valgrind the kernels are compiled for COUNT_CPU
(valgrind runs no AVX-512), so on an AVX-512 machine they are not the instructions a run there
executes; the same goes for a library such as Embree, which picks its code by the CPU it sees.

Needs `perf` (linux-tools; the VM allows cpu-clock sampling of its own processes), or valgrind
for --count, and binutils' `addr2line` and `readelf` (and `objdump` for --instructions, the N
hottest instructions). A diagnostic, not a benchmark: no peer (benchmarks/count_instructions.py
counts Embree's instructions beside raylume's); tests/test_profile_counts.py checks how it reads
callgrind's output.

`--hits MESH` profiles the batch query instead of a render: the hit rays of
benchmarks/bench_hits.py's frame (--width x --width; MESH a bumpy sphere's size, 40k or 4M, or
a model in ../shared/models) traced again and again by `intersect_rays` on 1 thread, the query
issue 49 times; with `--shadows`, bench_shadows.py's shadow rays by `occluded_rays`; with
`--singly`, either ray by ray (`closest_hit` or `any_hit` in the benchmarks' loops, as path mode
traces its bounces). Profiles of two meshes side by side show where a large mesh's extra time
goes.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# the line-table build's own Numba cache, under $NUMBA_CACHE_DIR or ~/.cache (Numba's cache keys
# leave out the compile flags: kernels compiled with full debug info must not be found here)
CACHE = "raylume-profile-lines"
# --count's kernels are compiled for a CPU without AVX-512, which valgrind cannot run (AVX2, FMA,
# BMI: every x86-64 this project's timings came from, less AVX-512); NUMBA_CPU_NAME overrides it
COUNT_CPU = "x86-64-v3"
COUNT_FEATURES = "+avx,+avx2,+fma,+bmi,+bmi2,+lzcnt,+popcnt,+f16c,+movbe,+sse4.2"
LANES = ("path_wave_lane", "path_lane", "trace_lane", "cast_lane", "aov_lane", "bdpt_lane")
BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


def _reexec_with_debug_info(count: bool) -> None:
    """Run this script again with the kernels' line tables on, in a cache of their own: once to
    compile them into it (where they are not yet), once to profile them as loaded from it. With
    `count`, the second run is under callgrind (_count_instructions) and this process reports
    what it counted: the kernels are then compiled for COUNT_CPU, which valgrind can run."""
    if os.environ.get("NUMBA_DEBUGINFO") == "1":
        return
    base = os.environ.get("NUMBA_CACHE_DIR") or str(Path.home() / ".cache")
    env = {**os.environ, "NUMBA_DEBUGINFO": "1", "NUMBA_CACHE_DIR": str(Path(base) / CACHE)}
    if count:
        # both: Numba's cache keys hold the CPU's name and features, and features left to Numba
        # are the host's (valgrind hides AVX-512): the run under valgrind would compile again
        env.setdefault("NUMBA_CPU_NAME", COUNT_CPU)
        env.setdefault("NUMBA_CPU_FEATURES", COUNT_FEATURES)
        folder = Path(tempfile.mkdtemp(prefix="raylume-count-"))
        grind = callgrind_command(folder) + [
            "--dump-instr=yes",
            "--dump-line=no",
            "--compress-pos=no",
            "--compress-strings=no",
        ]
        runs = [
            [sys.executable, *sys.argv, "--compile-only"],
            [*grind, sys.executable, *sys.argv, "--count-into", str(folder)],
        ]
    else:
        runs = [[sys.executable, *sys.argv, *extra] for extra in (["--compile-only"], [])]
    for command in runs:
        if code := subprocess.run(command, env=env).returncode:
            sys.exit(code)
    if count:
        _report_counts(folder)
    sys.exit(0)


def _line_tables_only() -> None:
    """NUMBA_DEBUGINFO alone compiles other code than a render runs: it marks every function
    `noinline`, turns bounds checks on and keeps every variable alive and in memory; renders took
    1.8-2.1x the time (examples/materials.toml, 128 x 128 x 16). Here only the line tables (and
    the inlined frames LLVM records in them) are added: the same inlining, no bounds checks, no
    kept variables. (Numba's `dbg_directives_only`, which means that, trips an assertion in
    llvmlite's LLVM on these kernels.)"""
    from numba.core import cpu, lowering

    finalize = cpu.CPUTargetOptions.finalize
    pre_lower = lowering.Lower.pre_lower

    def lines_only(self, flags, options):
        finalize(self, flags, options)
        flags.dbg_extend_lifetimes = False
        flags.boundscheck = False

    def inlinable(self):
        pre_lower(self)
        self.builder.function.attributes.discard("noinline")

    cpu.CPUTargetOptions.finalize = lines_only
    lowering.Lower.pre_lower = inlinable
    lowering.Lower._disable_sroa_like_opt = property(lambda self: False)


def _keep_objects() -> dict[str, bytes]:
    """Numba's cache loads each kernel from object code: keep it by library name, as it is read."""
    from numba.core import codegen

    objects: dict[str, bytes] = {}
    unserialize = codegen.CPUCodeLibrary._unserialize.__func__

    def keep(cls, cg, state):
        name, kind, data = state
        if kind == "object":
            objects[name] = data[0]
        return unserialize(cls, cg, state)

    codegen.CPUCodeLibrary._unserialize = classmethod(keep)
    return objects


def _run(*command: str) -> list[str]:
    return subprocess.run(command, capture_output=True, text=True).stdout.splitlines()


def _code_section(obj: Path, symbol: str) -> tuple[str, int, int]:
    """(the code section holding `symbol`, the symbol's offset in it, the section's size)."""
    sections = {}
    for line in _run("readelf", "-S", "-W", str(obj)):
        m = re.match(r"\s*\[\s*(\d+)\]\s+(\S+)\s+PROGBITS\s+\S+\s+\S+\s+([0-9a-f]+)\s+\S+\s+(\S*X\S*)", line)
        if m:
            sections[int(m.group(1))] = (m.group(2), int(m.group(3), 16))
    # the symbol table's Value (for an object file, the offset in its section) and Ndx columns
    found = [ln.split() for ln in _run("readelf", "-s", "-W", str(obj)) if ln.split()[-1:] == [symbol]]
    if not found:
        raise SystemExit(f"profile_kernels: {symbol[:60]}... is not in the kernel's object code")
    offset, index = int(found[0][1], 16), int(found[0][6])
    name, size = sections[index]
    return name, offset, size


def _instructions(obj: Path, section: str) -> dict[int, str]:
    """Per code offset in `section`, its instruction as objdump writes it."""
    code = {}
    for line in _run("objdump", "-d", "--no-show-raw-insn", "-j", section, str(obj)):
        m = re.match(r"\s*([0-9a-f]+):\s+(.*)", line)
        if m:
            code[int(m.group(1), 16)] = " ".join(m.group(2).split())
    return code


def _function(name: str) -> str:
    """A readable name for a mangled Numba function: its module path and own name
    (`_ZN7raylume7kernels8geometry5sweep9sweep_hitB4v1...` -> geometry.sweep.sweep_hit)."""
    if not name.startswith("_ZN"):
        return name[:60]
    rest, parts = name[3:], []
    while rest[:1].isdigit():
        digits = re.match(r"\d+", rest)
        start = digits.end()
        parts.append(rest[start : start + int(digits.group())])
        rest = rest[start + int(digits.group()) :]
    return ".".join(p for p in parts if p not in ("raylume", "kernels")) or name[:60]


def _frames(obj: Path, section: str, offsets: list[int]) -> dict[int, list[tuple[str, str]]]:
    """Per code offset, its inlined frames, innermost first: (function, file:line)."""
    out = subprocess.run(
        ["addr2line", "-j", section, "-e", str(obj), "-i", "-f", "-a", *[hex(o) for o in offsets]],
        capture_output=True,
        text=True,
    ).stdout.splitlines()
    frames: dict[int, list[tuple[str, str]]] = {}
    current, i = None, 0
    while i < len(out):
        if out[i].startswith("0x"):
            current = int(out[i], 16)
            frames[current] = []
            i += 1
            continue
        where = out[i + 1].split(" (")[0]
        where = where.split("/src/raylume/")[-1] if "/src/raylume/" in where else where
        frames[current].append((_function(out[i]), where))
        i += 2
    return frames


def _renders(args):
    """(a call that renders the scene once, the render kernels by name), the kernels loaded."""
    import raylume
    from raylume.kernels.integrators import frame

    builtin = args.scene in raylume.builtin_names() and not Path(args.scene).exists()
    session = raylume.Session(raylume.builtin_scene(args.scene) if builtin else raylume.load(args.scene))
    settings = {"width": args.width or 128, "height": args.height, "spp": args.spp, "threads": 1, "aovs": args.aovs}
    if args.mode:
        settings["mode"] = args.mode
    session.render(**{**settings, "width": 16, "height": 16, "spp": 1})
    return (lambda: session.render(**settings)), {name: getattr(frame, name) for name in LANES}


def _hit_rays(args):
    """(a call that traces bench_hits.py's hit rays on --hits once, or with --shadows
    bench_shadows.py's shadow rays, the batch query's kernel)."""
    import numpy as np

    sys.path.insert(0, str(BENCHMARKS))
    from bench_hits import _trace, _trace_singly, frame_rays, mesh, single_rays
    from bench_shadows import _blocked, _blocked_singly, any_hits, shadow_rays

    from raylume.kernels.geometry.query import intersect_lane, occluded_lane
    from raylume.kernels.geometry.wide_nodes import traversal_stacks

    found = mesh(args.hits)
    if found is None:
        raise SystemExit(f"profile_kernels: no mesh {args.hits!r} (a bumpy size such as 40k, or a shared model)")
    size = args.width or 1024
    frame = compiled, o, d, hit = frame_rays(*found, size)
    stacks = traversal_stacks()
    if args.shadows:
        _, so, sd, tmax = shadow_rays(*found, size, frame)
        args.rays = len(so)
        if args.singly:
            work, kernels = (lambda: _blocked_singly(compiled, so, sd, tmax, stacks)), {"any_hits": any_hits}
        else:
            work, kernels = (lambda: _blocked(compiled, so, sd, tmax)), {"occluded_lane": occluded_lane}
    else:
        o, d = np.ascontiguousarray(o[hit]), np.ascontiguousarray(d[hit])
        args.rays = len(o)
        if args.singly:
            work, kernels = (lambda: _trace_singly(compiled, o, d, stacks)), {"single_rays": single_rays}
        else:
            work, kernels = (lambda: _trace(compiled, o, d)), {"intersect_lane": intersect_lane}
    work()
    return work, kernels


def callgrind_command(folder: Path) -> list[str]:
    """valgrind's command line for callgrind with its counting off until count_calls switches it
    on, branch prediction simulated, its output (callgrind.out) and log in `folder`."""
    return [
        "valgrind", "--tool=callgrind", "--instr-atstart=no", "--branch-sim=yes",
        f"--callgrind-out-file={folder / 'callgrind.out'}", f"--log-file={folder / 'valgrind.log'}",
    ]  # fmt: skip


def count_calls(work, calls: int = 1) -> None:
    """(In a process under callgrind_command.) Count `calls` calls of `work`: callgrind's
    instrumentation switched on for them and off again."""
    pid = str(os.getpid())
    subprocess.run(["callgrind_control", "-i", "on", pid], check=True, stdout=subprocess.DEVNULL)
    for _ in range(calls):
        work()
    subprocess.run(["callgrind_control", "-i", "off", pid], check=True, stdout=subprocess.DEVNULL)


def _count_instructions(work, kernels, args) -> None:
    """(Under callgrind, instrumentation off.) Count --calls calls of `work`, and leave what the
    report needs beside callgrind's output. (Warm already: _hit_rays has called `work` once,
    _renders has rendered a small frame.)"""
    count_calls(work, args.calls)
    rows = [[name, entry, str(obj), section, offset, size] for name, entry, obj, section, offset, size in kernels]
    what = {"calls": args.calls, "rays": getattr(args, "rays", 0), "top": args.top, "instructions": args.instructions}
    what["kernels"] = rows
    (args.count_into / "kernels.json").write_text(json.dumps(what))


def _callgrind_costs(path: Path) -> tuple[list[str], dict[int, list[int]]]:
    """(event names, per instruction address its self costs) from a callgrind output written with
    --dump-instr=yes --dump-line=no --compress-pos=no: every cost line starts with its address;
    the line after `calls=` is a call's inclusive cost, which the callee's own lines hold already."""
    events: list[str] = []
    costs: dict[int, list[int]] = {}
    after_call = False
    with open(path) as lines:
        for line in lines:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line.startswith("calls="):
                after_call = True
            elif line.startswith("0x"):
                if after_call:
                    after_call = False
                    continue
                address, *values = line.split()
                here = costs.setdefault(int(address, 16), [0] * len(events))
                for k, v in enumerate(values):  # trailing zeros are left out
                    here[k] += int(v)
    return events, costs


def _report_counts(folder: Path) -> None:
    """Print what callgrind counted in the kernels (folder: _count_instructions's), per source
    line (innermost) and per function (with what is inlined into it): instructions (Ir) and
    the branches callgrind's model mispredicts (Bcm, conditional)."""
    what = json.loads((folder / "kernels.json").read_text())
    events, costs = _callgrind_costs(folder / "callgrind.out")
    ir, bcm = events.index("Ir"), events.index("Bcm")
    per = what["rays"] * what["calls"] or what["calls"]
    unit = "a ray" if what["rays"] else "a call"
    lines, functions = collections.defaultdict(lambda: [0, 0]), collections.defaultdict(lambda: [0, 0])
    total = [0, 0]
    hottest = []  # (instructions, kernel, offset: code, innermost line, mispredicted)
    for name, entry, obj, section, offset, size in what["kernels"]:
        offsets = {a - entry + offset: c for a, c in costs.items() if 0 <= a - entry + offset < size}
        code = _instructions(Path(obj), section) if what["instructions"] else {}
        for at, frames in _frames(Path(obj), section, sorted(offsets)).items():
            c = offsets[at]
            where = frames[0][1] if frames else "??"
            if code:
                hottest.append((c[ir], name, f"{at:x}: {code.get(at, '?')}", where, c[bcm]))
            total[0] += c[ir]
            total[1] += c[bcm]
            lines[where][0] += c[ir]
            lines[where][1] += c[bcm]
            for function in dict.fromkeys(f for f, _ in frames):
                functions[function][0] += c[ir]
                functions[function][1] += c[bcm]
    print(f"{what['calls']} call(s), counted under callgrind ({folder}): {total[0] / per:.0f} instructions {unit}")
    print(f"in the kernels, {total[1] / per:.2f} conditional branches {unit} mispredicted (callgrind's model)\n")
    for title, table in (("source line (innermost)", lines), ("function (with what is inlined into it)", functions)):
        print(f"| {title} | instructions | {unit} | mispredicted {unit} |\n| --- | --- | --- | --- |")
        for where, (n, m) in sorted(table.items(), key=lambda kv: -kv[1][0])[: what["top"]]:
            print(f"| {where} | {100 * n / (total[0] or 1):.1f}% | {n / per:.1f} | {m / per:.2f} |")
        print()
    if hottest:
        print(f"| kernel | instruction (offset: code) | source line | executed {unit} | mispredicted {unit} |")
        print("| --- | --- | --- | --- | --- |")
        for n, name, text, where, m in sorted(hottest, reverse=True)[: what["instructions"]]:
            print(f"| {name} | `{text}` | {where} | {n / per:.2f} | {m / per:.3f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", help="a scene file, mesh file or built-in name")
    parser.add_argument("--hits", metavar="MESH", help="profile bench_hits.py's hit rays on MESH instead")
    parser.add_argument("--shadows", action="store_true", help="with --hits: bench_shadows.py's shadow rays instead")
    parser.add_argument("--singly", action="store_true", help="with --hits: ray by ray, without packets")
    parser.add_argument("--mode", default=None, help="cast | trace | path (default: the scene's)")
    parser.add_argument("--width", type=int, default=None, help="128 for renders, 1024 for --hits")
    parser.add_argument("--height", type=int, default=128, help="renders only")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=8.0, help="how long to sample")
    parser.add_argument("--top", type=int, default=25, help="rows of each table")
    parser.add_argument("--aovs", action="store_true", help="render the AOV pass too (a render's default)")
    parser.add_argument("--instructions", type=int, default=0, metavar="N", help="also list the N hottest instructions")
    parser.add_argument("--count", action="store_true", help="count instructions under callgrind instead of sampling")
    parser.add_argument("--calls", type=int, default=1, help="with --count: how many calls are counted")
    parser.add_argument("--compile-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--count-into", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if (args.scene is None) == (args.hits is None):
        parser.error("give a SCENE or --hits MESH")
    if (args.shadows or args.singly) and not args.hits:
        parser.error("--shadows and --singly go with --hits MESH")
    needs = ("valgrind", "callgrind_control") if args.count else ("perf",)
    for tool in (*needs, "addr2line", "readelf", *(["objdump"] if args.instructions else [])):
        if shutil.which(tool) is None:
            raise SystemExit(f"profile_kernels: needs `{tool}` on the PATH")
    _reexec_with_debug_info(args.count)
    _line_tables_only()
    objects = _keep_objects()

    import numba

    numba.set_num_threads(1)
    if args.compile_only:
        print("loading, or compiling once (minutes for path mode), the kernels with line tables", flush=True)
    work, lanes = _hit_rays(args) if args.hits else _renders(args)
    if args.compile_only:
        return
    kernels = []  # (name, entry address, object file, code section, entry offset, section size)
    folder = args.count_into or Path(tempfile.mkdtemp(prefix="raylume-profile-"))
    for name, dispatcher in lanes.items():
        for _, cres in dispatcher.overloads.items():
            library = cres.library
            if library.name not in objects:
                continue  # compiled in this process, not loaded from the cache
            obj = folder / f"{name}.o"
            obj.write_bytes(objects[library.name])
            symbol = cres.fndesc.llvm_func_name
            entry = library.get_pointer_to_function(symbol)
            kernels.append((name, entry, obj, *_code_section(obj, symbol)))
    if not kernels:
        raise SystemExit("profile_kernels: no kernel was loaded from the cache (NUMBA_DEBUGINFO set by hand?)")
    if args.count_into:
        _count_instructions(work, kernels, args)
        return

    data = folder / "perf.data"
    record = ["perf", "record", "-e", "cpu-clock", "-F", "4000", "-o", str(data), "-p", str(os.getpid())]
    perf = subprocess.Popen(record, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)  # perf attaches
    started, renders = time.perf_counter(), 0
    while time.perf_counter() - started < args.seconds:
        work()
        renders += 1
    perf.send_signal(2)
    perf.wait()
    ips = subprocess.run(["perf", "script", "-i", str(data), "-F", "ip"], capture_output=True, text=True).stdout.split()
    samples = [int(ip, 16) for ip in ips]
    what = ("frames of shadow rays" if args.shadows else "frames of hit rays") if args.hits else "renders"
    print(f"{renders} {what}, {len(samples)} samples; {folder} holds the object code and perf.data\n")

    innermost, inclusive, by_kernel = collections.Counter(), collections.Counter(), collections.Counter()
    hottest = []  # (samples, kernel, instruction, innermost line)
    for name, entry, obj, section, offset, size in kernels:
        offsets = collections.Counter(ip - entry + offset for ip in samples if 0 <= ip - entry + offset < size)
        if not offsets:
            continue
        by_kernel[name] += sum(offsets.values())
        code = _instructions(obj, section) if args.instructions else {}
        for at, frames in _frames(obj, section, sorted(offsets)).items():
            n = offsets[at]
            if code:
                hottest.append((n, name, f"{at:x}: {code.get(at, '?')}", frames[0][1] if frames else "??"))
            innermost[frames[0][1] if frames else "??"] += n
            for function in dict.fromkeys(f for f, _ in frames):
                inclusive[function] += n
    total = len(samples) or 1
    shares = ", ".join(f"{name} {100 * n / total:.1f}%" for name, n in by_kernel.most_common())
    print(f"{100 * sum(by_kernel.values()) / total:.1f}% of the samples in the kernels ({shares})\n")
    print("| source line (innermost) | share |\n| --- | --- |")
    for where, n in innermost.most_common(args.top):
        print(f"| {where} | {100 * n / total:.1f}% |")
    print("\n| function (with what is inlined into it) | share |\n| --- | --- |")
    for function, n in inclusive.most_common(args.top):
        print(f"| {function} | {100 * n / total:.1f}% |")
    if hottest:
        # a sample lands on the instruction after the one that stalled (its skid): read the
        # instruction before each listed one too (objdump -d on the object file)
        print("\n| kernel | instruction (offset: code) | source line | share |\n| --- | --- | --- | --- |")
        for n, name, text, where in sorted(hottest, reverse=True)[: args.instructions]:
            print(f"| {name} | `{text}` | {where} | {100 * n / total:.1f}% |")


if __name__ == "__main__":
    main()
