"""Speed and memory of mrlib.metrics (coverage, diversity) against the naive oracles.

Run from the repository root::

    python bench/metrics_speed.py                 # everything (a few minutes on 2 cores)
    python bench/metrics_speed.py --sizes 300     # quick scaling check only
    python bench/metrics_speed.py --skip-scaling --skip-samples   # headline only

Three parts, results printed and written to ``bench/results/metrics_speed.json``:

1. **Scaling**: each metric (coverage, global diversity, local diversity) on a reference
   and a generated clip of ``L`` frames each, ``L`` in ``--sizes`` (300, 1500, 6000), fast
   and naive. A naive run is skipped when its time, extrapolated from the previous size
   with its complexity (windows ``O(L^2 w)``, PNN ``O(L^3)``), exceeds ``--naive-limit``
   seconds; the JSON says so.
2. **Headline**: global diversity of a 12,000-frame generated clip against a 6,000-frame
   reference, in a fresh process pinned to 2 CPU cores. Reports time and peak RSS.
3. **Samples**: all three metrics for 200 generated samples of 3,600 frames against a
   1,800-frame reference (2x a one-minute clip at 30 fps, the GANimator protocol), also
   in a fresh process on 2 cores. Samples are drawn one at a time from a seed, as a
   generator would produce them, so they are never all in memory.

Features are random, 144 channels (23 joints x 6D + 6 contacts), float32 as a network
would output them; the metrics' cost does not depend on the values.

Memory, two measures:

* ``tracemalloc`` peak during one call (scaling table): numpy registers its array
  buffers with tracemalloc, so this is the algorithm's own array footprint, excluding
  the interpreter, imported libraries and BLAS scratch space. It is measured in a second,
  traced run (tracing slows allocation-heavy loops, so times come from an untraced run).
* peak RSS of a fresh process (headline, samples; ``VmHWM``, else ``ru_maxrss``): the
  whole process, including the interpreter and torch (imported by mrlib), also
  reported separately as ``baseline_rss_mib`` right after the imports.

For global diversity the table also lists the memory GANimator's evaluation kernel would
allocate for its ``(L_gen, L_gen + 1, L_ref)`` float64 cost table (not run).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
from common import RESULTS, ROOT, describe, write_json

from mrlib import metrics as mt
from mrlib.metrics import oracles

DIM = 23 * 6 + 6


def features(T: int, seed: int) -> np.ndarray:
    """Random ``(T, 144)`` float32 features."""
    return np.random.default_rng(seed).standard_normal((T, DIM), dtype=np.float32)


def rss_mib() -> float:
    """Peak resident set size of this process so far, MiB.

    ``VmHWM`` from /proc (Linux) is the high-water mark of this process's own memory
    map; ``ru_maxrss`` can carry over the parent's peak across fork + exec, so it is only
    the fallback."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux


# name -> (fast, naive, exponent of L in the naive cost)
METRICS = {
    "coverage": (
        lambda g, r: mt.coverage(g, r, window=30),
        lambda g, r: oracles.coverage_naive(g, r, window=30),
        2,
    ),
    "global_diversity": (
        lambda g, r: mt.global_diversity(g, r, tmin=30),
        lambda g, r: oracles.global_diversity_naive(g, r, tmin=30)[0],
        3,
    ),
    "local_diversity": (
        lambda g, r: mt.local_diversity(g, r, window=15),
        lambda g, r: oracles.local_diversity_naive(g, r, window=15),
        2,
    ),
}


def timed(fn, *args) -> tuple[float, float]:
    t0 = time.perf_counter()
    value = fn(*args)
    return time.perf_counter() - t0, float(value)


def traced_peak_mib(fn, *args) -> float:
    tracemalloc.start()
    tracemalloc.reset_peak()
    fn(*args)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def scaling(sizes: list[int], naive_limit: float) -> list[dict]:
    rows = []
    last_naive: dict[str, tuple[int, float]] = {}
    for L in sizes:
        ref, gen = features(L, 0), features(L, 1)
        # inputs as float64 numpy, so neither side pays for conversion inside the timing
        ref64, gen64 = ref.astype(np.float64), gen.astype(np.float64)
        for name, (fast, naive, expo) in METRICS.items():
            row: dict = {"metric": name, "L_gen": L, "L_ref": L}
            row["fast_s"], value = timed(fast, gen64, ref64)
            row["fast_peak_traced_mib"] = traced_peak_mib(fast, gen64, ref64)
            row["value"] = value
            if name == "global_diversity":
                row["ganimator_table_gib"] = L * (L + 1) * L * 8 / 2**30
            estimate = None
            if name in last_naive:
                L0, t0 = last_naive[name]
                estimate = t0 * (L / L0) ** expo
            if estimate is not None and estimate > naive_limit:
                row["naive_skipped"] = (
                    f"estimated {estimate:.0f} s (> {naive_limit:.0f} s) from "
                    f"{last_naive[name][1]:.1f} s at L={last_naive[name][0]} and O(L^{expo})"
                )
            else:
                row["naive_s"], naive_value = timed(naive, gen64, ref64)
                last_naive[name] = (L, row["naive_s"])
                row["naive_value"] = naive_value
                row["abs_diff"] = abs(naive_value - value)
                row["speedup"] = row["naive_s"] / row["fast_s"]
                if row["naive_s"] < 30:
                    row["naive_peak_traced_mib"] = traced_peak_mib(naive, gen64, ref64)
                    row["memory_ratio"] = row["naive_peak_traced_mib"] / row["fast_peak_traced_mib"]
            rows.append(row)
            print(format_row(row), flush=True)
    return rows


def format_row(row: dict) -> str:
    s = (
        f"{row['metric']:17s} L={row['L_gen']:5d}  fast {row['fast_s']:7.3f} s "
        f"{row['fast_peak_traced_mib']:7.1f} MiB"
    )
    if "naive_s" in row:
        s += f" | naive {row['naive_s']:7.2f} s"
        if "naive_peak_traced_mib" in row:
            s += f" {row['naive_peak_traced_mib']:7.1f} MiB"
        s += f" | x{row['speedup']:.0f} faster"
        if "memory_ratio" in row:
            s += f", memory naive/fast {row['memory_ratio']:.1f}"
        s += f" | |diff| {row['abs_diff']:.1e}"
    else:
        s += f" | naive skipped: {row['naive_skipped']}"
    if "ganimator_table_gib" in row:
        s += f" | GANimator table {row['ganimator_table_gib']:.3g} GiB"
    return s


# --- child processes: a clean ru_maxrss, pinned to 2 cores --------------------------------
def child_headline() -> dict:
    out = {"baseline_rss_mib": rss_mib()}
    ref, gen = features(6000, 0), features(12000, 1)
    t0 = time.perf_counter()
    value, seg = mt.global_diversity(gen, ref, tmin=30, return_segmentation=True)
    out.update(
        seconds=time.perf_counter() - t0,
        peak_rss_mib=rss_mib(),
        value=value,
        n_segments=len(seg),
        L_gen=12000,
        L_ref=6000,
    )
    return out


def child_samples(n_samples: int) -> dict:
    out = {"baseline_rss_mib": rss_mib(), "n_samples": n_samples, "L_gen": 3600, "L_ref": 1800}
    ref = features(1800, 0)

    def samples():  # drawn one at a time, like a generator producing them
        for i in range(n_samples):
            yield features(3600, 1000 + i)

    t0 = time.perf_counter()
    for _ in samples():
        pass
    out["drawing_samples_s"] = time.perf_counter() - t0
    for name, fn in [
        ("coverage", lambda: mt.coverage(samples(), ref, window=30)),
        ("global_diversity", lambda: mt.global_diversity(samples(), ref, tmin=30)),
        ("local_diversity", lambda: mt.local_diversity(samples(), ref, window=15)),
    ]:
        t0 = time.perf_counter()
        out[name] = {"value": fn(), "seconds": time.perf_counter() - t0}
    out["total_s"] = sum(
        out[k]["seconds"] for k in ("coverage", "global_diversity", "local_diversity")
    )
    out["peak_rss_mib"] = rss_mib()
    return out


def run_child(flag: str, extra: list[str]) -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="2", OPENBLAS_NUM_THREADS="2", MKL_NUM_THREADS="2")
    cmd = [sys.executable, __file__, flag, *extra]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def pin_two_cores() -> list[int]:
    if hasattr(os, "sched_setaffinity"):
        cores = sorted(os.sched_getaffinity(0))[:2]
        os.sched_setaffinity(0, cores)
        return cores
    return []


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--sizes", type=int, nargs="+", default=[300, 1500, 6000], help="clip lengths L"
    )
    ap.add_argument(
        "--naive-limit", type=float, default=60.0, help="skip naive runs estimated slower (s)"
    )
    ap.add_argument("--samples", type=int, default=200, help="samples for the protocol run")
    ap.add_argument("--skip-scaling", action="store_true", help="skip the scaling table")
    ap.add_argument("--skip-headline", action="store_true", help="skip the 12k x 6k PNN run")
    ap.add_argument("--skip-samples", action="store_true", help="skip the 200-sample protocol run")
    ap.add_argument("--out", type=Path, default=RESULTS / "metrics_speed.json")
    ap.add_argument("--child-headline", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--child-samples", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()

    if args.child_headline or args.child_samples:
        cores = pin_two_cores()
        res = child_headline() if args.child_headline else child_samples(args.samples)
        res["cores"] = cores
        print(json.dumps(res))
        return

    print(describe(), flush=True)
    results: dict = {}
    if not args.skip_scaling:
        print(f"== scaling (L_gen = L_ref = L, D = {DIM}); peak = tracemalloc ==")
        results["scaling"] = scaling(args.sizes, args.naive_limit)
    if not args.skip_headline:
        print("== headline: global diversity, 12000 generated vs 6000 reference frames, 2 cores ==")
        h = run_child("--child-headline", [])
        h["pass"] = h["seconds"] < 60 and h["peak_rss_mib"] < 1024
        results["headline"] = h
        print(
            f"{h['seconds']:.2f} s, peak RSS {h['peak_rss_mib']:.0f} MiB "
            f"(after imports {h['baseline_rss_mib']:.0f} MiB), cores {h['cores']}, "
            f"{h['n_segments']} segments -> {'PASS' if h['pass'] else 'FAIL'} (< 60 s, < 1 GiB)"
        )
    if not args.skip_samples:
        print(f"== {args.samples} samples x 3600 frames vs 1800 reference frames, 2 cores ==")
        s = run_child("--child-samples", ["--samples", str(args.samples)])
        results["samples"] = s
        for k in ("coverage", "global_diversity", "local_diversity"):
            print(f"{k:17s} {s[k]['seconds']:7.1f} s  value {s[k]['value']:.4f}")
        print(
            f"total {s['total_s']:.1f} s "
            f"(+{s['drawing_samples_s']:.1f} s per pass drawing samples), "
            f"peak RSS {s['peak_rss_mib']:.0f} MiB (after imports {s['baseline_rss_mib']:.0f} MiB)"
        )
    print(f"wrote {write_json('metrics_speed', results, args.out)}")


if __name__ == "__main__":
    main()
