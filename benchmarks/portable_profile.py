"""The portable profile (FAMARL_REPRO=portable): what it costs, and whether it removes the instruction-set
dependence that an AVX2 host would show against this one.

    python benchmarks/portable_profile.py [--epochs 300] [--steps 100000]

Each measurement runs in a fresh interpreter, because the profile must be in place before numpy and torch load:
- cost: a FAVAE fit (the C_last-calibrated fit of ``famarl macros``, ``--epochs`` epochs on 100 pushed-down-only
  demos' segments) and a 100k-step training run of each agent, native vs portable, CPU seconds of the work alone;
- instruction sets: the same fit and a FaMARL run under this machine's ISA and under an emulated AVX2 host
  (ATen's kernels held at AVX2, oneDNN capped at AVX2, numpy's AVX-512 kernels off), each result hashed. On an
  AVX2 host itself the native hashes cannot differ; on an AVX-512 host they show what a second machine would see.

Emulation is not a second host: MKL picks its own kernels per CPU (MKL_CBWR, which the profile sets, is what
pins them), and only two real hosts can prove the profile.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from common import RESULTS, command_line, record, write_result

AVX2_HOST = {
    "ATEN_CPU_CAPABILITY": "avx2",
    "ONEDNN_MAX_CPU_ISA": "AVX2",
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
}

WORK = r"""
import hashlib, json, sys, time
from pathlib import Path
from famarl_cli.core.reproducibility import one_thread, platform_facts
one_thread()
import torch
from famarl_cli.stages import method as stages
from famarl_cli.rl import Agent
from famarl_cli.rl.ppo import PPOConfig
from famarl_cli.rl.spec import RunSpec
from famarl_cli.rl.training import Run

folder, epochs, steps = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
out = {"platform": platform_facts()}
start = time.process_time()
fitted = stages.fit(stages.FitOptions(segments=folder / "segments.h5", out=folder / "out" / "favae.pt",
                                      calibration=folder / "calibration.json", epochs=epochs, seed=0))
out["favae_cpu_s"] = time.process_time() - start
state = torch.load(folder / "out" / "favae.pt", weights_only=True)["state_dict"]
out["favae_hash"] = hashlib.sha256(b"".join(v.numpy().tobytes() for v in state.values())).hexdigest()[:16]
for agent in ("famarl", "ppo", "figar"):
    n_steps = {"famarl": 16, "figar": 32, "ppo": 128}[agent]
    spec = RunSpec("famarl/ContinuousWorld-Maze-v0", Agent(agent), 0, PPOConfig(total_steps=steps, n_steps=n_steps),
                   favae=str(folder / "out" / "favae.pt") if agent == "famarl" else None)
    run = Run.start(spec)
    start = time.process_time()
    run.trainer.train()
    out[f"{agent}_cpu_s"] = time.process_time() - start
    log = json.dumps(run.own.log, sort_keys=True).encode()
    out[f"{agent}_hash"] = hashlib.sha256(log).hexdigest()[:16]
print(json.dumps(out))
"""


def measure(folder: Path, epochs: int, steps: int, profile: str, host: dict) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in AVX2_HOST}
    env |= host | {"FAMARL_REPRO": profile}
    done = subprocess.run(
        [sys.executable, "-c", WORK, str(folder), str(epochs), str(steps)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def prepare(folder: Path) -> None:
    """Segments of 100 pushed-down-only demos and their C_last (made once, natively; the fit reads them)."""
    famarl = [sys.executable, "-m", "famarl_cli"]
    subprocess.run([*famarl, "demos", "--out", folder / "demos.h5", "--no-plot"], check=True, capture_output=True)
    subprocess.run(
        [*famarl, "segment", "--demos", folder / "demos.h5", "--out", folder / "segments.h5", "--no-plot"],
        check=True,
        capture_output=True,
    )
    subprocess.run(
        [*famarl, "favae", "calibrate", "--segments", folder / "segments.h5", "--epochs", "300", "--out",
         folder / "calibration.json"],
        check=True,
        capture_output=True,
    )  # fmt: skip


def records(results: dict[str, dict], command: str) -> dict[str, dict]:
    """measured.json's entry: the portable profile's CPU time over the native one, for each piece of work."""
    names = {"favae": "FAVAE fit", "famarl": "FaMARL", "ppo": "PPO", "figar": "FiGAR"}
    native, portable = results["native, this host"], results["portable, this host"]
    ratios = {w: portable[f"{w}_cpu_s"] / native[f"{w}_cpu_s"] for w in names}
    costs = ", ".join(f"{name} {ratios[w]:.2f}x" for w, name in names.items())
    return {
        "portable_profile": {
            "what": "the portable profile's cost",
            "command": command,
            "measured": f"{costs} the native CPU time",
            "values": ratios,
            "unit": "x",
            "better": "lower",
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--out", type=Path, default=RESULTS / "portable_profile.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temp:
        folder = Path(temp)
        prepare(folder)
        results = {
            f"{profile}, {name}": measure(folder, args.epochs, args.steps, profile, host)
            for profile in ("native", "portable")
            for name, host in (("this host", {}), ("emulated AVX2 host", AVX2_HOST))
        }
    work = ("favae", "famarl", "ppo", "figar")
    print(f"{'':34}" + "".join(f"{w:>22}" for w in work))
    for name, result in results.items():
        cells = "".join(f"{result[f'{w}_cpu_s']:>8.1f} s {result[f'{w}_hash']:>11}" for w in work)
        print(f"{name:34}{cells}")
    for w in work:
        native = results["native, this host"][f"{w}_cpu_s"]
        portable = results["portable, this host"][f"{w}_cpu_s"]
        print(f"  {w}: portable costs {portable / native:.2f}x the CPU time of native")
    for profile in ("native", "portable"):
        same = [w for w in work if results[f"{profile}, this host"][f"{w}_hash"] ==
                results[f"{profile}, emulated AVX2 host"][f"{w}_hash"]]  # fmt: skip
        print(f"  {profile}: identical on both hosts: {', '.join(same) or 'nothing'}")
    write_result(args.out, {"args": {"epochs": args.epochs, "steps": args.steps}, "results": results})
    for name, entry in records(results, command_line(__file__, parser, args)).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
