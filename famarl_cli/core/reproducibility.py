"""What decides an artifact's floats, recorded in its provenance, and the opt-in *portable* profile.

Fixed seeds give byte-identical artifacts on one machine. Across machines, torch's CPU kernels differ by
instruction set (AVX2, AVX-512): oneDNN picks its convolution kernels per ISA, ATen's softmax/log_softmax have
AVX-512 variants, MKL's and numpy's kernels dispatch per CPU, and the thread count changes reductions. Adam
turns a last-bit difference into a full learning-rate step, so training runs diverge from the first update.

``FAMARL_REPRO=portable``, set in the environment before famarl starts, removes every ISA dependence we could
measure: one thread, MKL's conditional numerical reproducibility (``MKL_CBWR=COMPATIBLE``, the only value that
works on both vendors' CPUs), ATen held at its AVX2 kernels, numpy's AVX-512 kernels off, and oneDNN and NNPACK
off so that convolutions take ATen's own path. It costs CPU time (docs/verdicts.md has the measured cost); the
default, ``native``, uses the fastest kernels of the machine. The environment must be in place before numpy loads
and before torch runs its first operation (which fixes its kernels), so :mod:`famarl_cli` applies it when it is
first imported, and :func:`one_thread` refuses to go on when torch's kernels were fixed before.
"""

from __future__ import annotations

import os
import sys

from famarl_cli.core.errors import UsageError

PROFILE_VARIABLE = "FAMARL_REPRO"
PROFILES = ("native", "portable")
PORTABLE_ENVIRONMENT = {
    "MKL_CBWR": "COMPATIBLE",
    "ATEN_CPU_CAPABILITY": "avx2",
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
}
"""Read by MKL, torch and numpy when they load."""
KNOBS = tuple(PORTABLE_ENVIRONMENT) + ("ONEDNN_MAX_CPU_ISA",)
"""Environment variables recorded in provenance (the last one caps oneDNN's ISA; it is how we emulate an AVX2
host on an AVX-512 one)."""


def profile() -> str:
    value = os.environ.get(PROFILE_VARIABLE, "native") or "native"
    if value not in PROFILES:
        raise UsageError(f"{PROFILE_VARIABLE}={value!r}; expected one of {', '.join(PROFILES)}")
    return value


def apply_environment() -> None:
    """Put the portable profile's variables in place (a no-op for the native profile). Must run before numpy and
    torch are imported; later, it changes nothing that is already loaded."""
    if os.environ.get(PROFILE_VARIABLE) == "portable":
        os.environ.update(PORTABLE_ENVIRONMENT)


def one_thread() -> None:
    """One torch thread (small networks train fastest so, and the thread count changes results), and the
    portable profile's backends when it is on."""
    import torch

    torch.set_num_threads(1)
    if profile() == "portable":
        if torch.backends.cpu.get_cpu_capability().startswith("AVX512"):
            raise UsageError(
                f"{PROFILE_VARIABLE}=portable must be set before famarl (or torch) is imported; set it in the shell"
            )
        torch.backends.mkldnn.enabled = False
        torch.backends.nnpack.set_flags(False)


def platform_facts() -> dict:
    """The facts that decide an artifact's floats: the profile, library versions, the CPU capability torch
    dispatches to, threads and the environment knobs. Only what is already loaded is asked (the demos stage never
    loads torch)."""
    import numpy as np

    facts: dict = {
        "profile": profile(),
        "python": sys.version.split()[0],
        "numpy": str(np.__version__),
        "knobs": {name: os.environ[name] for name in KNOBS if name in os.environ},
    }
    torch = sys.modules.get("torch")
    if torch is not None:
        facts.update(
            torch=str(torch.__version__),
            cpu_capability=torch.backends.cpu.get_cpu_capability(),
            threads=torch.get_num_threads(),
            mkldnn=bool(torch.backends.mkldnn.enabled),
        )
    return facts


def machine() -> str:
    """The machine in words, for tables that say where their numbers come from: the CPU's model, its widest
    vector instructions (which decide torch's floats) and its cores, e.g. "AMD EPYC 7B13, AVX2, 2 cores"."""
    model, flags = "unknown CPU", set()
    try:
        for line in open("/proc/cpuinfo", encoding="utf-8"):
            key, _, value = line.partition(":")
            if key.strip() == "model name" and model == "unknown CPU":
                model = " ".join(value.split())
            elif key.strip() == "flags" and not flags:
                flags = set(value.split())
    except OSError:  # not Linux: the model is what platform knows
        import platform

        model = platform.processor() or platform.machine() or model
    isa = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else None
    return ", ".join(part for part in (model, isa, f"{os.cpu_count()} cores") if part)


def source_revision(folder: str = ".") -> str | None:
    """The git commit the code in ``folder`` is at (short hash), with "+changes" when famarl's code or the
    pipelines' definitions differ from it there; None outside a git checkout."""
    import subprocess

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", *args], cwd=folder, capture_output=True, text=True, check=True, timeout=30
        ).stdout.strip()

    try:
        head = git("rev-parse", "--short=7", "HEAD")
        changed = git("status", "--porcelain", "--untracked-files=no", "--", "famarl_cli", "*dvc.yaml", "*params.yaml")
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{head}+changes" if changed else head
