"""A sweep's aggregate training throughput on this machine's cores: famarl sweep with 1 and with N local workers,
against Stable-Baselines3 running the same seeds in N processes, and the peak memory of each worker.

    pip install -e ".[bench]"
    python benchmarks/sweep_throughput.py [--seeds 4] [--steps 300000] [--jobs 1 2] [--agent ppo]

Every run is PPO (or --agent) on the Maze with ``famarl train``'s defaults, which are ppo_vs_sb3.py's settings for
PPO. The time of a sweep runs from the plan to the last run's end, worker start-up (importing torch) included: it
is what ``dvc repro`` pays. Aggregate env steps/s = every run's env steps over that time. SB3 runs one seed per
process, N processes at a time (multiprocessing, fork-free), each with one torch thread.
"""

from __future__ import annotations

import argparse
import multiprocessing
import tempfile
import threading
import time
from pathlib import Path

import psutil
from common import RESULTS, command_line, record, rounded, step_count, verdict, write_result


def our_sweep(seeds: int, steps: int, jobs: int, agent: str) -> dict:
    from famarl_cli.cli.sweep import plan
    from famarl_cli.sweep.driver import run_sweep
    from famarl_cli.sweep.executors import make_executor

    peaks: dict[int, float] = {}
    done = threading.Event()

    def watch() -> None:
        me = psutil.Process()
        while not done.is_set():
            for child in me.children(recursive=True):
                try:
                    peaks[child.pid] = max(peaks.get(child.pid, 0.0), child.memory_info().rss / 2**20)
                except psutil.Error:
                    pass
            time.sleep(0.2)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    with tempfile.TemporaryDirectory() as folder:
        planned = plan("train", ["--agent", agent, "--steps", str(steps)], f"0-{seeds - 1}", [], None)
        start = time.perf_counter()
        with make_executor(jobs) as executor:
            state = run_sweep(Path(folder) / "runs", planned, executor)
        seconds = time.perf_counter() - start
    done.set()
    watcher.join()
    assert not state.failed, [s.error for s in state.failed]
    total = sum(s.result["env_steps"] for s in state.jobs)
    workers = sorted(peaks.values(), reverse=True)[:jobs] if jobs > 1 else []
    return {"seconds": seconds, "env_steps": total, "rate": total / seconds, "worker_peak_rss_mib": workers}


def _sb3_seed(args: tuple[int, int]) -> int:
    import torch
    from ppo_vs_sb3 import stable_baselines3

    torch.set_num_threads(1)
    steps, seed = args
    return stable_baselines3(steps, seed)["env_steps"]


def sb3_processes(seeds: int, steps: int, jobs: int) -> dict:
    start = time.perf_counter()
    with multiprocessing.get_context("forkserver").Pool(jobs) as pool:
        total = sum(pool.map(_sb3_seed, [(steps, seed) for seed in range(seeds)], chunksize=1))
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "env_steps": total, "rate": total / seconds}


def records(seeds: int, steps: int, agent: str, ours: dict[int, dict], sb3: dict | None, command: str) -> dict:
    """measured.json's entries: the most workers' aggregate rate against one worker's and against SB3's on as many
    processes, and the largest peak RSS of a sweep worker (where more than one worker ran)."""
    most, least = max(ours), min(ours)
    name = {"ppo": "PPO", "figar": "FiGAR", "famarl": "FaMARL"}.get(agent, agent)
    measured = f"{rounded(ours[most]['rate'])} env steps/s"
    values, units = {f"workers_{most}": ours[most]["rate"]}, {f"workers_{most}": "env steps/s"}
    targets = []
    if most != least:
        speedup = ours[most]["rate"] / ours[least]["rate"]
        measured = f"{rounded(ours[most]['rate'])} against {rounded(ours[least]['rate'])} env steps/s: "
        measured += f"**{speedup:.2f}x**" + verdict(speedup >= 1.8)
        targets.append(">= 1.8x")
        values |= {f"workers_{least}": ours[least]["rate"], "speedup": speedup}
        units |= {f"workers_{least}": "env steps/s", "speedup": "x"}
    if sb3:
        over = ours[most]["rate"] / sb3["rate"]
        measured += f"; SB3 on the same {most} cores {rounded(sb3['rate'])} (ours {over:.1f}x)" + verdict(over >= 10)
        targets.append(">= 10x SB3")
        values |= {"sb3": sb3["rate"], "over_sb3": over}
        units |= {"sb3": "env steps/s", "over_sb3": "x"}
    entries = {
        "sweep_throughput": {
            "what": f"a sweep on {most} local workers against {least} ({seeds} {name} seeds x {step_count(steps)})",
            "command": command,
            "measured": measured,
            "target": "; ".join(targets),
            "values": values,
            "unit": units,
            "better": {name: "higher" for name, unit in units.items() if unit == "x"},
        }
    }
    if peaks := [peak for result in ours.values() for peak in result["worker_peak_rss_mib"]]:
        entries["sweep_throughput_peak_rss"] = {
            "what": "peak RSS of a sweep worker",
            "command": command,
            "measured": f"{max(peaks):.0f} MiB" + verdict(max(peaks) < 1024),
            "target": "< 1 GiB",
            "value": max(peaks),
            "unit": "MiB",
        }
    return entries


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--agent", default="ppo")
    parser.add_argument("--no-sb3", action="store_true", help="Skip Stable-Baselines3.")
    parser.add_argument("--out", type=Path, default=RESULTS / "sweep_throughput.json")
    args = parser.parse_args()
    ours = {jobs: our_sweep(args.seeds, args.steps, jobs, args.agent) for jobs in args.jobs}
    most = max(args.jobs)
    sb3 = None if args.no_sb3 else sb3_processes(args.seeds, args.steps, most)
    print(f"{args.seeds} seeds x {args.steps:,} steps of {args.agent} on the Maze")
    for jobs, result in ours.items():
        memory = (
            f", worker peak RSS {max(result['worker_peak_rss_mib']):.0f} MiB" if result["worker_peak_rss_mib"] else ""
        )
        print(f"  famarl sweep, {jobs} worker(s): {result['seconds']:.1f} s, {result['rate']:,.0f} env steps/s{memory}")
    if len(ours) > 1:
        print(f"  speed-up of {most} workers over 1: {ours[most]['rate'] / ours[min(args.jobs)]['rate']:.2f}x")
    if sb3:
        print(f"  SB3, {most} processes: {sb3['seconds']:.1f} s, {sb3['rate']:,.0f} env steps/s")
        print(f"  famarl sweep / SB3 at {most} at once: {ours[most]['rate'] / sb3['rate']:.1f}x")
    write_result(args.out, {"args": vars(args) | {"out": str(args.out)}, "ours": ours, "sb3": sb3})
    command = command_line(__file__, parser, args)
    for name, entry in records(args.seeds, args.steps, args.agent, ours, sb3, command).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
