"""The pass matrix of the trained-model tests: training seeds x torch thread counts.

A test of a trained model (``tests/test_control.py``, ``tests/test_restyle.py``) asserts a
statistical claim about a GAN trained for a few hundred iterations; whether one training
run satisfies it is a draw that depends on the seed and on the float kernels of the
machine (thread count, SIMD width). This script trains the tests' recipes
(``tests/trained_models.py``) for each training seed and thread count, and their
negatives (the same recipe untrained, or with the loss term the claim depends on
ablated), and prints the quantities the tests assert on, with the test's bound, so a
bound is committed only where it holds with margin over the matrix and fails on the
negatives.

    python tests/trained_test_matrix.py --recipe synthetic --seeds 0-4 --threads 1,2
    python tests/trained_test_matrix.py --recipe detail --seeds 0-4 --threads 1 --jobs 2
    python tests/trained_test_matrix.py --recipe detail --variant ablated --seeds 0-1
    python tests/trained_test_matrix.py --recipe detail --seeds 0-4 --threads 1 --fine-noise 0,0.5,1
    python tests/trained_test_matrix.py --recipe restyle --seeds 0-2 [--variant untrained]
    python tests/trained_test_matrix.py --summary          # the table of the saved rows

A script beside the recipes it trains, not a test (pytest collects ``test_*.py`` only);
run it from the repository root. Rows are appended to
``bench/results/trained_test_matrix.jsonl`` (one per run).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results" / "trained_test_matrix.jsonl"

# the bounds the tests assert (tests/test_control.py, test_restyle.py), on aggregates over
# the cases
BOUNDS = {
    "synthetic": {"low_mean": 0.3, "low_min": 0.0},
    "detail": {"low_mean": 0.1, "high_mean": 0.3},
    "reconstruction": {"max_error_below": 0.0},  # 0.08 - the worst clip's error
    "restyle": {"log_mean": 0.5, "log_min": 0.0},  # recipe 4: the recipe-2 model restyling
}


def _ints(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def run_one(
    recipe: str, variant: str, seed: int, threads: int, fine_noises: list[float] | None = None
) -> list[dict]:
    """Train one model in this process and measure it: a row per sampler ``fine_noise``
    (default: mrlib's ``FINE_NOISE``)."""
    import trained_models as tm

    from mrlib.io import default_data_dir
    from mrlib.representation.body import load_body_model
    from mrlib.sampling.sampler import FINE_NOISE, Sampler
    from mrlib.threads import use

    use(threads)  # explicit: mrlib's own calls keep it (mrlib.threads)
    body = load_body_model()
    iterations = 2 if variant == "untrained" else 300
    t0 = time.time()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        if recipe == "synthetic":
            if variant == "ablated":
                raise SystemExit("the synthetic recipe has no ablated variant")
            cfg = tm.synthetic_config(seed, iterations)
            model = tm.train_recipe(tm.synthetic_clips(body), cfg, tmp, body, threads)
        elif recipe == "reconstruction":
            if variant == "ablated":
                raise SystemExit("the reconstruction recipe has no ablated variant")
            cfg = tm.reconstruction_config(seed, 2 if variant == "untrained" else 40)
            model = tm.train_recipe(tm.reconstruction_clips(), cfg, tmp, body, threads)
        else:  # detail, and restyle with the same model (recipe 4 restyles with recipe 2's)
            if recipe == "restyle" and variant == "ablated":
                raise SystemExit("the restyle recipe has no ablated variant")
            cfg = tm.detail_config(seed, iterations, detail=0.0 if variant == "ablated" else None)
            clips = tm.detail_clips(default_data_dir(), body)
            model = tm.train_recipe(clips, cfg, tmp, body, threads)
        train_s = time.time() - t0
        inputs = tm.restyle_inputs(default_data_dir()) if recipe == "restyle" else None
        for fine in fine_noises or [FINE_NOISE]:
            sampler = Sampler(fine_noise=fine, fix_contacts=False)  # the quantities' draws
            if recipe == "synthetic":
                r = tm.low_band_log_ratios(model, sampler=sampler)
                row = {"low": r.tolist(), "low_mean": float(r.mean()), "low_min": float(r.min())}
            elif recipe == "reconstruction":
                e = tm.reconstruction_errors(model)
                row = {"errors": e.tolist(), "max_error_below": float(0.08 - e.max())}
            elif recipe == "restyle":
                r = tm.restyle_log_ratios(model, inputs, sampler=sampler)
                row = {
                    "log": r[:, 0].tolist(),
                    "log_mean": float(r[:, 0].mean()),
                    "log_min": float(r[:, 0].min()),
                    "nearest_target": float(r[:, 1].mean()),  # residual nearest the target
                }
            else:
                r = tm.band_log_ratios(model, sampler=sampler)
                row = {
                    "low": r[:, 0].tolist(),
                    "high": r[:, 1].tolist(),
                    "low_mean": float(r[:, 0].mean()),
                    "high_mean": float(r[:, 1].mean()),
                }
            row.update(recipe=recipe, variant=variant, seed=seed, threads=threads)
            row.update(fine_noise=float(fine), train_s=round(train_s, 1))
            row.update(total_s=round(time.time() - t0, 1))
            rows.append(row)
    return rows


def passes(row: dict) -> bool:
    b = BOUNDS[row["recipe"]]
    return all(row[k] > v for k, v in b.items())


def summary(rows: list[dict], fine_noise: float | None = None) -> str:
    """The table of ``rows`` drawn with the sampler's ``fine_noise`` (default: today's
    ``mrlib.sampling.sampler.FINE_NOISE``; rows saved before it was recorded drew at 1)."""
    from mrlib.sampling.sampler import FINE_NOISE

    fine = FINE_NOISE if fine_noise is None else fine_noise
    latest = {}  # the last row saved for each run
    for r in rows:
        latest[(r["recipe"], r["variant"], r["seed"], r["threads"], r.get("fine_noise", 1.0))] = r
    rows = list(latest.values())
    lines = [f"samples drawn with fine_noise={fine:g}; the latest row of each run"]
    for recipe in BOUNDS:
        keys = list(BOUNDS[recipe])
        sel = [r for r in rows if r["recipe"] == recipe and r.get("fine_noise", 1.0) == fine]
        if not sel:
            continue
        bound = ", ".join(f"{k} > {v}" for k, v in BOUNDS[recipe].items())
        lines += [f"\n{recipe} (test asserts {bound})", ""]
        lines.append("| variant | seed | threads | " + " | ".join(keys) + " | passes | train s |")
        lines.append("|---|---|---|" + "---|" * len(keys) + "---|---|")
        for r in sorted(sel, key=lambda r: (r["variant"], r["seed"], r["threads"])):
            vals = " | ".join(f"{r[k]:+.3f}" for k in keys)
            lines.append(
                f"| {r['variant']} | {r['seed']} | {r['threads']} | {vals} | "
                f"{'yes' if passes(r) else 'NO'} | {r['train_s']:.0f} |"
            )
        for variant in ("trained", "untrained", "ablated"):
            v = [r for r in sel if r["variant"] == variant]
            if v:
                worst = {k: min(r[k] for r in v) for k in keys}
                lines.append(
                    f"\n{variant}: {sum(map(passes, v))} of {len(v)} pass; worst "
                    + ", ".join(f"{k} {x:+.3f}" for k, x in worst.items())
                )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recipe", choices=sorted(BOUNDS), default="synthetic")
    ap.add_argument("--variant", choices=["trained", "untrained", "ablated"], default="trained")
    ap.add_argument("--seeds", default="0-4", help="e.g. 0-4 or 0,2,5")
    ap.add_argument("--threads", default="1,2", help="torch thread counts, e.g. 1,2")
    ap.add_argument("--jobs", type=int, default=1, help="runs at a time (each in its own process)")
    ap.add_argument("--summary", action="store_true", help="print the table of saved rows and exit")
    ap.add_argument(
        "--fine-noise", default=None,
        help="sampler fine_noise values to measure each model with, e.g. 0,0.5,1 (with "
        "--summary: the one to show) [default: mrlib's]",
    )  # fmt: skip
    ap.add_argument("--one", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.summary:
        rows = [json.loads(x) for x in RESULTS.read_text().splitlines()] if RESULTS.exists() else []
        fine = None if args.fine_noise is None else float(args.fine_noise)
        print(summary(rows, fine) if rows else f"no rows in {RESULTS}")
        return 0
    fines = None if args.fine_noise is None else [float(x) for x in args.fine_noise.split(",")]
    if args.one:
        print(
            json.dumps(
                run_one(args.recipe, args.variant, int(args.seeds), int(args.threads), fines)
            )
        )
        return 0
    runs = [(s, t) for s in _ints(args.seeds) for t in _ints(args.threads)]

    def launch(st):
        cmd = [sys.executable, __file__, "--one", "--recipe", args.recipe]
        cmd += ["--variant", args.variant, "--seeds", str(st[0]), "--threads", str(st[1])]
        if args.fine_noise is not None:
            cmd += ["--fine-noise", args.fine_noise]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
        return json.loads(proc.stdout.strip().splitlines()[-1])

    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    rows = []
    with ThreadPoolExecutor(args.jobs) as pool:
        for got in pool.map(launch, runs):
            for row in got:
                rows.append(row)
                with RESULTS.open("a") as f:
                    f.write(json.dumps(row) + "\n")
                print(f"seed {row['seed']} threads {row['threads']} fine_noise "
                      f"{row['fine_noise']:g}: pass={passes(row)} {row}", flush=True)  # fmt: skip
    for fine in fines or [None]:
        print(summary(rows, fine))
    return 0


if __name__ == "__main__":
    sys.exit(main())
