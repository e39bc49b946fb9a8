"""FAVAE designs side by side: what the variants studies share (the designs, one fit of one, its scores).

A design is everything about a FAVAE that is not the data, the beta of the fit or the seed: its decoder, what the
capacities constrain, progressive training, the heads, how C_last becomes capacities, the pre-run's beta and the
latent sizes. :func:`fit_design` runs the C_last pre-run and the fit of one design on one set of segments, then
scores it: per ladder the KL, the information and what is left of the KL (the shift), the active latents, the
reconstruction, the length accuracy, MIG with its interval, each variable's traversal effect and the time per
optimiser step. :func:`run_all` runs many (design, seed) fits at once on famarl sweep's executors (study.fan_out).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, replace

import numpy as np

from famarl_cli.method.favae import CALIBRATION_BETA


@dataclass(frozen=True)
class Design:
    decoder: str = "ladder"
    measure: str = "information"
    progressive: float = 0.0
    head: str = "flatten"
    capacity: str = "measured"
    calibration_beta: float = CALIBRATION_BETA
    dims: tuple[int, ...] = (2, 2, 2)


DESIGNS = {
    # the design before the ladder decoder, and the variants measured on it (docs/favae.md)
    "shared-kl": Design("shared", "kl"),
    "shared-kl-pool": Design("shared", "kl", head="pool"),
    "shared-kl-deepest": Design("shared", "kl", capacity="deepest"),
    "shared-kl-half": Design("shared", "kl", capacity="half"),
    # one change at a time, then together
    "ladder-kl": Design("ladder", "kl"),
    "shared-info": Design("shared", "information"),
    "ladder-info": Design("ladder", "information"),
    "shared-info-prog": Design("shared", "information", progressive=2 / 3),
    "ladder-info-prog": Design("ladder", "information", progressive=2 / 3),
    "ladder-info-p20": Design("ladder", "information", progressive=0.2),
    "ladder-info-p40": Design("ladder", "information", progressive=0.4),
    "ladder-kl-prog": Design("ladder", "kl", progressive=2 / 3),
    "ladder-info-pool": Design("ladder", "information", head="pool"),
    "ladder-info-pool-prog": Design("ladder", "information", progressive=2 / 3, head="pool"),
    "ladder-info-b1": Design("ladder", "information", calibration_beta=1.0),
    "ladder-info-prog-b1": Design("ladder", "information", progressive=2 / 3, calibration_beta=1.0),
}


def fit_design(job: dict) -> dict:
    """One design on one set of segments: pre-run, fit, scores. ``job`` holds ``design`` (a name of
    :data:`DESIGNS`), ``seed``, ``beta``, ``epochs``, ``segments`` (a path or ``padded``, ``lengths``, ``factors``),
    ``values`` and ``draw`` (traversal). A job of :func:`~study.fan_out`, which puts torch on one thread."""
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.method.favae.model import FavaeConfig
    from famarl_cli.method.favae.training import TrainingParams, allocate_capacity, calibrate, evaluate_fit, train_favae
    from famarl_cli.method.traversal import traverse, variables_of

    design = DESIGNS[job["design"]]
    if "segments" in job:
        loaded = read_segments(job["segments"])
        padded, lengths, factors = loaded.padded, loaded.length, loaded.factors
    else:
        padded, lengths, factors = job["padded"], job["lengths"], job["factors"]
    base = FavaeConfig(action_dim=padded.shape[2] - 2, length=padded.shape[1])
    config = replace(base, decoder=design.decoder, head=design.head, latent_dims=design.dims)
    params = TrainingParams(
        epochs=job["epochs"], seed=job["seed"], measure=design.measure, progressive=design.progressive
    )
    start = time.perf_counter()
    c_last, pre_log = calibrate(padded, config, params, beta=design.calibration_beta)
    ladders = len(design.dims)
    pre_run = {
        "design": job["design"],
        **asdict(design),
        "seed": job["seed"],
        "c_last": c_last,
        "pre_run_kl": [pre_log[-1][f"kl_{i + 1}"] for i in range(ladders)],
        "pre_run_information": [pre_log[-1][f"information_{i + 1}"] for i in range(ladders)],
    }
    if job.get("pre_run_only"):
        seconds = time.perf_counter() - start
        steps = job["epochs"] * math.ceil(len(padded) / params.batch_size)
        return {**pre_run, "beta": None, "seconds": round(seconds, 1), "ms_per_step": round(1000 * seconds / steps, 2)}
    capacities = allocate_capacity(c_last, design.capacity)
    model, log = train_favae(padded, config, job["beta"], capacities, params)
    seconds = time.perf_counter() - start
    steps = 2 * job["epochs"] * math.ceil(len(padded) / params.batch_size)
    scores = evaluate_fit(model, padded, lengths, factors)
    variables = variables_of(model, None, None)
    effects = traverse(model, variables, job["values"], draw=job["draw"]).effects
    per_ladder = np.split(effects, np.cumsum(design.dims)[:-1])
    return {
        **pre_run,
        "beta": job["beta"],
        "capacities": capacities,
        **{key: scores[key] for key in SCORES},
        "effect_per_variable": {f"({lad},{i})": float(e) for (lad, i), e in zip(variables, effects, strict=True)},
        "effect_per_ladder": [float(e.max()) for e in per_ladder],
        "seconds": round(seconds, 1),
        "ms_per_step": round(1000 * seconds / steps, 2),
    }


SCORES = (
    "mig",
    "mig_interval",
    "mig_per_factor",
    "mig_per_factor_interval",
    "reconstruction_mse",
    "length_accuracy",
    "kl_per_ladder",
    "information_per_ladder",
    "shift_per_ladder",
    "active_per_ladder",
    "kl_per_dim",
    "information_per_dim",
)


def run_all(jobs: list[dict], workers: int | None = None, ray_address: str | None = None) -> list[dict]:
    """Every job, ``workers`` at once on famarl sweep's executors (:func:`study.fan_out`: by default $FAMARL_JOBS,
    else one per usable core; a Ray cluster at ``ray_address``), each torch on one thread; results in the order of
    ``jobs``, each printed as it comes."""
    from study import fan_out

    return fan_out(fit_design, jobs, workers, ray_address, each=lambda fit: print(line(fit), flush=True))


def line(fit: dict) -> str:
    def numbers(key: str) -> str:
        return "/".join(f"{v:.2f}" for v in fit[key])

    if fit["beta"] is None:
        return (
            f"{fit['design']:22s} seed {fit['seed']} pre-run: C_last {numbers('c_last')}  KL "
            f"{numbers('pre_run_kl')}  {fit['ms_per_step']} ms/step"
        )
    return (
        f"{fit['design']:22s} seed {fit['seed']} beta {fit['beta']:g}: C_last {numbers('c_last')}  "
        f"KL {numbers('kl_per_ladder')}  info {numbers('information_per_ladder')}  "
        f"effect {numbers('effect_per_ladder')}  MIG {fit['mig']:.3f}  len {fit['length_accuracy']:.2f}  "
        f"MSE {fit['reconstruction_mse']:.4f}  {fit['ms_per_step']} ms/step"
    )


def summary(fits: list[dict], keys: tuple[str, ...]) -> dict:
    """Per design (and beta), the mean of each key over seeds and the per-seed values."""
    groups: dict[tuple, list[dict]] = {}
    for fit in fits:
        groups.setdefault((fit["design"], fit["beta"]), []).append(fit)
    return {
        f"{design} beta {beta}": {
            key: {"mean": np.mean([f[key] for f in group], axis=0).tolist(), "per_seed": [f[key] for f in group]}
            for key in keys
        }
        for (design, beta), group in groups.items()
    }
