"""Training and sampling speed on an idle and on a busy machine: mrlib's thread policy
(``mrlib.threads``) against PyTorch's default thread count.

Run from the repository root::

    python bench/busy_machine.py                  # ~4 min on 2 otherwise idle cores
    python bench/busy_machine.py --extras         # + Adam variants, masking, torch.compile
    python bench/busy_machine.py --busy 2 --iterations 20 --repeats 3

What is timed: the ``demo`` preset (the ``tutorial`` networks, one critic step per
generator step) on ``data_samples/walk_happy.npz`` and ``walk_sad.npz`` at the preset's
15 fps, ``--iterations`` training iterations of each of its four blocks after one
warm-up iteration per block (``mrlib.training.trainer.Trainer.step``), then ``--samples`` raw and
foot-contact cleaned samples of a training clip's length (``mrlib.sampling.generation.generate``).
Every measurement runs in a fresh process:

* ``policy``: mrlib as it is, ``mrlib.threads.use()`` with no thread variable
  set: the count a training run fixes at its start (``mrlib.threads.run_threads``), what
  ``mrlib train`` and ``Trainer.fit`` do;
* ``torch``: the same code on PyTorch's own thread count (one per physical core), kept
  by setting ``OMP_NUM_THREADS`` to it;
* ``before``: what mrlib did before it had a policy: PyTorch's count, Adam's for-loop
  implementation and the skeleton convolutions' weight masked at every call (idle only).

``policy`` and ``torch`` run once on the idle machine and once beside ``--busy``
CPU-bound processes (a Python busy loop each; default one). The table gives iterations
per second over all four blocks (each block's best of ``--repeats`` rounds, so that a
burst of other work spoils one round of one block, not the figure), the busy/idle
slowdown measured in the same run, and the policy's idle speed as a share of the others'.
``--extras`` adds, idle and on the policy's thread count, Adam's three implementations
(for-loop, foreach, fused; ``mrlib.training.build.make_adam`` picks fused where the torch build
has it) and the per-call weight masking against mrlib's (blocks 1 and 4), and
``torch.compile`` of the finest block's generator levels with its start-up time.

Writes ``bench/results/busy_machine.json``, with the 1-minute load average at the start
of each measurement and the CPU seconds per wall second the process got
(``cpu_per_wall``). Timings are wall-clock: on a machine shared with other work, read
them with those.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

from common import ROOT, describe, write_json

CLIPS = [ROOT / "data_samples" / "walk_happy.npz", ROOT / "data_samples" / "walk_sad.npz"]
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
BUSY_LOOP = "import os\np = os.getppid()\nwhile os.getppid() == p:\n    pass"  # ends with us
ADAM = {"loop": {"foreach": False}, "foreach": {"foreach": True}, "fused": {"fused": True}}


# -- one measurement, in a child process --------------------------------------------------------
def _mask_every_call() -> None:
    """The skeleton convolution as it was: the weight masked by a product at every call."""
    import torch.nn.functional as F

    from mrlib.model.skeleton_conv import SkeletonConv1d

    def forward(self, x, pad_index=None, circular=False):
        if pad_index is None:
            xp = F.pad(x, (self.pad, self.pad), mode="circular" if circular else "reflect")
        else:
            xp = x.gather(2, pad_index.expand(x.shape[0], x.shape[1], -1))
        return F.conv1d(xp, self.weight * self.mask, self.bias)

    SkeletonConv1d.forward = forward


def measure(blocks, iterations, samples, adam: str, mask_copy: bool, compile_: bool) -> dict:
    import torch

    from mrlib.model.presets import get_preset
    from mrlib.threads import use
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import Trainer

    threads = use()  # mrlib's policy; keeps OMP_NUM_THREADS where it is set
    if mask_copy:
        _mask_every_call()
    data = TrainingSet.from_files(CLIPS, fps=get_preset("demo").fps)
    tr = Trainer(data, get_preset("demo"), "/tmp/mrlib-bench-busy-unused")
    out: dict = {"threads": threads, "adam": adam, "mask_copy": mask_copy, "compile": compile_}
    out["blocks"] = {}
    total_t = total_n = 0.0
    for b in blocks:
        tr.block, tr.iteration = b, 0
        tr.start_block()
        if adam != "mrlib":
            for name in ("opt_g", "opt_d"):
                params = getattr(tr, name).param_groups[0]["params"]
                c = tr.config
                opt = torch.optim.Adam(params, lr=c.lr, betas=c.betas, **ADAM[adam])
                setattr(tr, name, opt)
        if compile_:
            for i in tr.block_levels:
                tr.generator.levels[i] = torch.compile(tr.generator.levels[i], dynamic=True)
        t0 = time.perf_counter()
        tr.step()  # warm-up
        if compile_:
            tr.step()  # the no-grad and the grad graphs compile on the first two steps
        warm = time.perf_counter() - t0
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(iterations):
            tr.step()
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        rate = iterations / dt
        out["blocks"][b] = {"it_per_s": rate, "warmup_s": warm, "cpu_per_wall": cpu / dt}
        total_t += dt
        total_n += iterations
    out["it_per_s"] = total_n / total_t
    out["threads_end"] = torch.get_num_threads()
    if samples:
        from mrlib.model.trained import model_from_trainer
        from mrlib.sampling.generation import generate
        from mrlib.sampling.sampler import Sampler

        tr.done = True
        model = model_from_trainer(tr)
        for key, clean in (("raw_ms", False), ("cleaned_ms", True)):
            sampler = Sampler(fix_contacts=clean)
            generate(model, model.labels[0], seed=0, sampler=sampler)  # warm-up
            times = []
            for k in range(samples):
                t0 = time.perf_counter()
                generate(model, model.labels[k % len(model.labels)], seed=k, sampler=sampler)
                times.append(1000 * (time.perf_counter() - t0))
            out[key] = statistics.median(times)
    return out


# -- the parent: processes, background load, tables ---------------------------------------------
def _busy(n: int) -> list[subprocess.Popen]:
    procs = [subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) for _ in range(n)]
    time.sleep(0.5)  # let them take their cores
    return procs


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        p.kill()
    for p in procs:
        p.wait()


def run_child(env_threads: int | None, busy: int, child_args: list[str]) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    if env_threads is not None:
        env["OMP_NUM_THREADS"] = str(env_threads)
    procs = _busy(busy)
    load = os.getloadavg()[0]
    try:
        cmd = [sys.executable, __file__, "--child", *child_args]
        res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    finally:
        _stop(procs)
    line = [x for x in res.stdout.splitlines() if x.startswith("RESULT ")]
    if res.returncode or not line:
        print(res.stderr[-3000:], file=sys.stderr)
        raise SystemExit(f"measurement {child_args} failed")
    row = json.loads(line[0][7:])
    row["loadavg_1min_at_start"] = load
    return row


def _args(a, blocks: str, samples: int, adam="mrlib", mask_copy=False, compile_=False):
    out = ["--blocks", blocks, "--iterations", str(a.iterations), "--samples", str(samples)]
    out += ["--adam", adam]
    return out + (["--mask-copy"] if mask_copy else []) + (["--compile"] if compile_ else [])


def _best_of(a: dict | None, b: dict) -> dict:
    """Per block the faster of two rounds, and the shorter sampling times: a burst of
    other work on a shared machine spoils one block of one round, not the figure."""
    if a is None:
        return b
    out = dict(a)
    out["blocks"] = {k: max(a["blocks"][k], b["blocks"][k], key=lambda v: v["it_per_s"])
                     for k in a["blocks"]}  # fmt: skip
    out["it_per_s"] = len(out["blocks"]) / sum(1 / v["it_per_s"] for v in out["blocks"].values())
    for key in ("raw_ms", "cleaned_ms"):
        if key in a:
            out[key] = min(a[key], b[key])
    return out


def _per_block(row: dict) -> str:
    return ", ".join(f"block {int(k) + 1} {v['it_per_s']:.2f}" for k, v in row["blocks"].items())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--iterations", type=int, default=10, help="timed iterations per block")
    ap.add_argument("--blocks", default="0,1,2,3", help="0-based blocks to time")
    ap.add_argument("--samples", type=int, default=3, help="timed samples of each kind")
    ap.add_argument("--busy", type=int, default=1, help="CPU-bound processes for 'busy'")
    ap.add_argument("--repeats", type=int, default=2, help="rounds; the best one is kept")
    ap.add_argument("--loads", default="idle,busy", help="'idle', 'busy' or both [both]")
    ap.add_argument("--extras", action="store_true", help="also Adam, masking, torch.compile")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--adam", default="mrlib", help=argparse.SUPPRESS)
    ap.add_argument("--mask-copy", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--compile", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    blocks = [int(b) for b in a.blocks.split(",")]
    if a.child:
        row = measure(blocks, a.iterations, a.samples, a.adam, a.mask_copy, a.compile)
        print("RESULT " + json.dumps(row))
        return

    import torch

    torch_default = torch.get_num_threads()  # this process never changes it
    print(describe(), flush=True)
    started = time.time()
    meta = {
        "torch_default_threads": torch_default,
        "iterations_per_block": a.iterations,
        "blocks": blocks,
        "busy_processes": a.busy,
        "repeats": a.repeats,
        "loadavg_at_start": os.getloadavg(),
    }
    cases = [  # (mode, load, OMP_NUM_THREADS, child arguments)
        ("policy", "idle", None, _args(a, a.blocks, a.samples)),
        ("torch", "idle", torch_default, _args(a, a.blocks, a.samples)),
        ("before", "idle", torch_default, _args(a, a.blocks, a.samples, "loop", True)),
        ("policy", "busy", None, _args(a, a.blocks, a.samples)),
        ("torch", "busy", torch_default, _args(a, a.blocks, a.samples)),
    ]
    best: dict[tuple[str, str], dict] = {}
    rows = []
    cases = [c for c in cases if c[1] in a.loads.split(",")]
    for r in range(a.repeats):
        for mode, load, env_threads, child in cases:
            row = run_child(env_threads, a.busy if load == "busy" else 0, child)
            row.update(mode=mode, load=load, repeat=r)
            rows.append(row)
            best[(mode, load)] = _best_of(best.get((mode, load)), row)
            print(
                f"round {r + 1} {mode:6s} {load:4s} {row['threads']} thread(s): "
                f"{row['it_per_s']:6.2f} it/s ({_per_block(row)}), raw {row['raw_ms']:.0f} ms, "
                f"cleaned {row['cleaned_ms']:.0f} ms (load {row['loadavg_1min_at_start']:.2f})",
                flush=True,
            )

    print(
        f"\ndemo preset, {len(blocks)} block(s) x {a.iterations} iterations, beside {a.busy} "
        f"busy process(es), best of {a.repeats}:\n\n"
        "| mrlib | threads | idle it/s | busy it/s | busy/idle | raw ms idle / busy "
        "| cleaned ms idle / busy |\n|---|---|---|---|---|---|---|"
    )
    names = {
        "policy": "with the policy",
        "torch": "on torch's count",
        "before": "before (for-loop Adam, masked copies)",
    }
    summary: dict = {}
    for mode in ("policy", "torch", "before"):
        i, b = best.get((mode, "idle")), best.get((mode, "busy"))
        if not (i or b):
            continue
        summary[mode] = {"threads": (i or b)["threads"]}
        cells = []
        for key, fmt in (("it_per_s", "{:.2f}"), ("raw_ms", "{:.0f}"), ("cleaned_ms", "{:.0f}")):
            cells.append([fmt.format(r[key]) if r else "-" for r in (i, b)])
            for load, r in (("idle", i), ("busy", b)):
                if r:
                    summary[mode][f"{load}_{key}"] = r[key]
        slow = i["it_per_s"] / b["it_per_s"] if i and b else None
        summary[mode]["slowdown"] = slow
        print(
            f"| {names[mode]} | {summary[mode]['threads']} | {cells[0][0]} | {cells[0][1]} | "
            f"{f'{slow:.2f}x' if slow else '-'} | {' / '.join(cells[1])} | {' / '.join(cells[2])} |"
        )

    def ratio(m1, l1, m2, l2):
        if (m1, l1) in best and (m2, l2) in best:
            return best[(m1, l1)]["it_per_s"] / best[(m2, l2)]["it_per_s"]
        return None

    summary.update(
        policy_idle_vs_before=ratio("policy", "idle", "before", "idle"),
        policy_idle_vs_torch=ratio("policy", "idle", "torch", "idle"),
        policy_busy_vs_torch=ratio("policy", "busy", "torch", "busy"),
    )
    show = lambda v: "-" if v is None else f"{v:.2f}x"  # noqa: E731
    print(
        f"\nwith the policy: busy/idle {show(summary['policy']['slowdown'])} (target <= 1.5x); "
        f"idle {show(summary['policy_idle_vs_before'])} the speed before it (target >= 0.90x), "
        f"{show(summary['policy_idle_vs_torch'])} the same code on torch's count; busy "
        f"{show(summary['policy_busy_vs_torch'])} as fast as on torch's count"
    )

    extras = _extras(a, summary["policy"]["threads"], summary) if a.extras else []
    meta["loadavg_at_end"] = os.getloadavg()
    meta["wall_s"] = time.time() - started
    result = {"meta": meta, "summary": summary, "rows": rows, "extras": extras}
    path = write_json("busy_machine", result)
    print(f"\nwrote {path} ({meta['wall_s']:.0f} s)")


def _extras(a, threads: int, summary: dict) -> list[dict]:
    """Adam variants and per-call masking (blocks 1 and 4), torch.compile (block 4): idle,
    the policy's thread count, best of ``--repeats`` interleaved rounds."""
    print(f"\nextras: idle, {threads} thread(s), {a.iterations} iterations per block")
    variants = {
        "adam loop": _args(a, "0,3", 0, "loop"),
        "adam foreach": _args(a, "0,3", 0, "foreach"),
        "adam fused": _args(a, "0,3", 0, "fused"),
        "masked copy per call": _args(a, "0,3", 0, "fused", mask_copy=True),
    }
    extras, best = [], {}
    for r in range(a.repeats):
        for name, child in variants.items():
            row = run_child(None, 0, child)
            row.update(kind=name, repeat=r)
            extras.append(row)
            best[name] = max(best.get(name, 0.0), row["it_per_s"])
            print(f"  round {r + 1} {name:21s} {row['it_per_s']:6.2f} it/s ({_per_block(row)})")
    fused, loop = best["adam fused"], best["adam loop"]
    summary.update(
        adam_fused_vs_loop=fused / loop,
        adam_foreach_vs_loop=best["adam foreach"] / loop,
        mask_once_vs_per_call=fused / best["masked copy per call"],
    )
    print(
        f"  Adam fused / for-loop {fused / loop:.3f}x, foreach / for-loop "
        f"{summary['adam_foreach_vs_loop']:.3f}x; masking the gradient once instead of the "
        f"weight per call {summary['mask_once_vs_per_call']:.3f}x"
    )
    rows = {}
    for compile_ in (False, True):
        row = run_child(None, 0, _args(a, "3", 0, compile_=compile_))
        row.update(kind="torch.compile" if compile_ else "eager")
        extras.append(row)
        rows[compile_] = row["blocks"]["3"]
        print(
            f"  block 4 {row['kind']:13s} {rows[compile_]['it_per_s']:6.2f} it/s, warm-up "
            f"{rows[compile_]['warmup_s']:.1f} s"
        )
    saved = 1 / rows[False]["it_per_s"] - 1 / rows[True]["it_per_s"]
    cost = rows[True]["warmup_s"] - rows[False]["warmup_s"]
    after = cost / saved if saved > 0 else None
    summary.update(compile_startup_s=cost, compile_pays_after_iterations=after)
    pays = f"after {after:.0f} iterations of the block" if after else "never (not faster)"
    print(f"  torch.compile: {cost:.0f} s of start-up, pays {pays}")
    return extras


if __name__ == "__main__":
    main()
