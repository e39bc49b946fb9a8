"""The file-to-file stages of the method after the demos: segment, the FAVAE pre-run and fit, and the traversal.

Each function reads its input files, runs the method (:mod:`~famarl_cli.method.segmentation`,
:mod:`~famarl_cli.method.favae.training`, :mod:`~famarl_cli.method.traversal`) and writes its outputs with their
provenance. The CLI commands and :mod:`~famarl_cli.stages.macros` (all of them for one seed, into one folder) call
these, so a stage writes the same files whichever way it runs. Progress goes to the optional ``on_epoch`` callbacks.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from famarl_cli.artifacts import prepare_output, provenance, read_demos, write_csv, write_json
from famarl_cli.artifacts.segments import Segments, read_segments, write_segments
from famarl_cli.core.errors import ArtifactError, UsageError
from famarl_cli.method.favae import CALIBRATION_BETA, DECODER


@dataclass(frozen=True)
class SegmenterOptions:
    """The window autoencoder's shape and training (the rest of the stage's options are SegmentParams)."""

    window: int = 4
    code_dim: int = 4
    hidden: int = 32
    epochs: int = 300


@dataclass
class Segmented:
    segments: Segments
    metrics: dict
    written: list[Path]


def segment(
    demos: Path,
    out: Path,
    params,
    segmenter: SegmenterOptions | None = None,
    encoder: Path | None = None,
    plot: bool = True,
    on_epoch: Callable[[int, float], None] | None = None,
    episodes: int | None = None,
) -> Segmented:
    """Cut ``demos`` (only its first ``episodes`` episodes, when given) into macro actions; writes ``out``
    (segments), ``.metrics.json``, the segmenter's ``.segmenter.pt`` (unless a trained ``encoder`` is given) and
    ``.png``. ``params`` is a SegmentParams."""
    from famarl_cli.method.segmentation import (
        AutoencoderConfig,
        TrainingConfig,
        load_autoencoder,
        save_autoencoder,
        segment_demos,
        train_autoencoder,
    )
    from famarl_cli.report.plots import plot_segmentation

    out = prepare_output(out)
    segmenter = segmenter or SegmenterOptions()
    metrics_path, segmenter_path = out.with_suffix(".metrics.json"), out.with_suffix(".segmenter.pt")
    loaded = read_demos(demos)
    if episodes is not None:
        if not 1 <= episodes <= len(loaded.episodes):
            raise UsageError(f"{demos} holds {len(loaded.episodes)} episodes; cannot take the first {episodes}")
        loaded = replace(loaded, episodes=loaded.episodes[:episodes])
    options = {**asdict(params), **asdict(segmenter), "episodes": episodes}
    inputs = [demos] + ([encoder] if encoder else [])
    if encoder:
        model, train_mse = load_autoencoder(encoder), None
    else:
        config = AutoencoderConfig(
            window=segmenter.window,
            action_dim=loaded.episodes[0].actions.shape[1],
            hidden=segmenter.hidden,
            code_dim=segmenter.code_dim,
        )
        model, train_mse = train_autoencoder(
            [e.actions for e in loaded.episodes], config, TrainingConfig(epochs=segmenter.epochs), params.seed, on_epoch
        )
    segments, metrics = segment_demos(loaded, model, params)
    metrics["autoencoder_mse"] = train_mse
    segments.provenance = provenance("famarl segment", options, params.seed, inputs)
    write_segments(out, segments)
    written = [out]
    if not encoder:
        save_autoencoder(segmenter_path, model, provenance("famarl segment", options, params.seed, [demos]))
        written.append(segmenter_path)
    # The metrics last: their presence says the stage finished (famarl_cli.stages.macros resumes by it).
    if plot:
        plot_segmentation(loaded, segments, out.with_suffix(".png"))
        written.append(out.with_suffix(".png"))
    write_json(metrics_path, metrics)
    written.append(metrics_path)
    return Segmented(segments, metrics, written)


def favae_setup(segments: Path, ladders: int, latent_dim: int, head: str = "flatten", decoder: str = DECODER):
    """The segments and the FAVAE config they call for (L and D come from the segments file)."""
    from famarl_cli.method.favae.model import FavaeConfig

    loaded = read_segments(segments)
    try:
        config = FavaeConfig(
            action_dim=loaded.action_dim,
            length=loaded.max_length,
            latent_dims=(latent_dim,) * ladders,
            channels=tuple(min(32 * 2**i, 64) for i in range(ladders)),
            head=head,
            decoder=decoder,
        )
    except ValueError as exc:
        raise UsageError(f"{exc}; re-run famarl segment with a --length divisible by {2**ladders}") from exc
    return loaded, config


def calibrate(
    segments: Path,
    out: Path,
    ladders: int,
    latent_dim: int,
    params,
    on_epoch: Callable[[dict], None] | None = None,
    *,
    head: str = "flatten",
    decoder: str = DECODER,
    beta: float = CALIBRATION_BETA,
) -> tuple[list[float], list[dict]]:
    """The C_last pre-run on ``segments`` at ``beta``, written to ``out`` (JSON); returns
    C_last and the pre-run's log. ``params`` is a TrainingParams."""
    from famarl_cli.method.favae.checkpoint import write_calibration
    from famarl_cli.method.favae.training import calibrate as run_calibration

    out = prepare_output(out)
    loaded, config = favae_setup(segments, ladders, latent_dim, head, decoder)
    c_last, log = run_calibration(loaded.padded, config, params, on_epoch, beta)
    options = {**asdict(params), "calibration_beta": beta, "config": config.to_dict()}
    write_calibration(
        out, c_last, config, provenance("famarl favae calibrate", options, params.seed, [segments]), params, beta
    )
    return c_last, log


@dataclass
class Fitted:
    scores: dict
    """evaluate_fit's scores plus beta, C_last, the final KL per ladder and the number of segments."""
    c_last: list[float]
    written: list[Path]


def fit(
    segments: Path,
    out: Path,
    beta: float,
    calibration: Path | None,
    ladders: int,
    latent_dim: int,
    params,
    on_epoch: Callable[[str, dict], None] | None = None,
    *,
    head: str = "flatten",
    capacity: str = "measured",
    decoder: str = DECODER,
    calibration_beta: float = CALIBRATION_BETA,
) -> Fitted:
    """Fit FAVAE on ``segments`` (after the C_last pre-run at ``calibration_beta``, written beside ``out``, unless
    ``calibration`` is given) and score it; writes the checkpoint ``out``, ``.log.csv`` and ``.metrics.json``.
    ``on_epoch`` gets the phase ("calibrate" or "fit") and the epoch's log row. ``capacity`` says how the pre-run's
    C_last becomes the capacities the fit anneals to (:func:`famarl_cli.method.favae.training.allocate_capacity`)."""
    from famarl_cli.method.favae.checkpoint import read_calibration, save_favae
    from famarl_cli.method.favae.training import allocate_capacity, evaluate_fit, train_favae, training_summary

    out = prepare_output(out)
    loaded, config = favae_setup(segments, ladders, latent_dim, head, decoder)
    inputs, log = [segments], []

    def phase(name: str):
        return None if on_epoch is None else (lambda row: on_epoch(name, row))

    if calibration:
        c_last = read_calibration(calibration, config, params)
        inputs.append(calibration)
    else:
        c_last, calibration_log = calibrate(
            segments,
            out.with_suffix(".calibration.json"),
            ladders,
            latent_dim,
            params,
            phase("calibrate"),
            head=head,
            decoder=decoder,
            beta=calibration_beta,
        )
        log += [{"phase": "calibrate", **row} for row in calibration_log]
    capacities = allocate_capacity(c_last, capacity)
    model, fit_log = train_favae(loaded.padded, config, beta, capacities, params, phase("fit"))
    log += [{"phase": "fit", **row} for row in fit_log]
    scores = evaluate_fit(model, loaded.padded, loaded.length, loaded.factors)
    training = {**training_summary(params, beta, c_last), "capacity": capacity, "capacities": capacities}
    options = {**training, "ladders": ladders, "latent_dim": latent_dim}
    # the information each latent carries travels with the model: famarl traverse names an empty ladder by it
    summary = {**training, "kl_per_dim": scores["kl_per_dim"], "information_per_dim": scores["information_per_dim"]}
    save_favae(out, model, summary, provenance("famarl favae fit", options, params.seed, inputs))
    metrics = {
        **scores,
        "beta": beta,
        "c_last": c_last,
        "capacity": capacity,
        "capacities": capacities,
        "final_kl_per_ladder": [fit_log[-1][f"kl_{i + 1}"] for i in range(config.ladders)],
        "segments": len(loaded.length),
        "factor_names": list(loaded.factor_names),
    }
    write_csv(out.with_suffix(".log.csv"), log)
    # The metrics last: their presence says the stage finished (famarl_cli.stages.macros resumes by it).
    write_json(out.with_suffix(".metrics.json"), metrics)
    return Fitted(metrics, c_last, [out, out.with_suffix(".log.csv"), out.with_suffix(".metrics.json")])


MANUAL_FAVAE = Path("data/favae/pushed-down-only.pt")
"""Where famarl favae fit writes by default, after famarl demos and famarl segment with their defaults."""
PIPELINE_FAVAE = Path("data/maze/macros/seed0/favae.pt")
"""Replicate 0 of the default pipeline's FAVAEs (dvc repro)."""


def default_favae() -> Path:
    """The FAVAE ``famarl traverse`` takes without ``--model``: the manual chain's, else the main job's replicate 0."""
    for path in (MANUAL_FAVAE, PIPELINE_FAVAE):
        if path.is_file():
            return path
    raise ArtifactError(
        f"no FAVAE to traverse: neither {MANUAL_FAVAE} (famarl demos --script pushed-down-only, famarl segment, "
        f"famarl favae fit) nor {PIPELINE_FAVAE} (dvc repro) exists; make one, or give --model"
    )


def traverse(
    model: Path,
    out: Path,
    values: list[float],
    ladder: int | None = None,
    index: int | None = None,
    draw: str = "run",
    env_id: str | None = None,
    env_kwargs: dict | None = None,
    dims: tuple[int, int] = (0, 1),
    frames: bool = False,
    world: str | None = None,
):
    """Traverse the FAVAE in ``model`` in the empty ``world`` of a famarl env family (default: the paper's), or in
    the gymnasium env ``env_id`` when given, drawing observation ``dims``. Writes ``out``
    (HDF5), ``.png`` and ``.json`` (effect per variable, in the path's units, and the information and KL each
    carries, nats, where the checkpoint records them) and, with ``frames``, ``.frames.png`` (what the env renders
    at the end of each macro action). Returns the Traversal and a Carried: what each traversed variable carries."""
    from famarl_cli.artifacts.traversal import write_traversal
    from famarl_cli.envs import DEFAULT_WORLD
    from famarl_cli.method.favae.checkpoint import load_favae
    from famarl_cli.method.traversal import traverse as run_traversal
    from famarl_cli.method.traversal import variables_of
    from famarl_cli.report.plots import plot_traversal, plot_traversal_frames

    out = prepare_output(out)
    favae, payload = load_favae(model)
    if frames and env_id is None:
        raise UsageError("--frames goes with --env: the frames are what that env renders")
    world = world or DEFAULT_WORLD
    variables = variables_of(favae, ladder, index)
    result = run_traversal(favae, variables, values, draw, env_id, env_kwargs, dims, frames, world)
    variables = result.variables.tolist()
    training = payload.get("training", {})

    def per_variable(key: str) -> list[float] | None:
        values = training.get(key)
        return None if values is None else [float(values[favae.config.latent_index(*v)]) for v in variables]

    carried = Carried(per_variable("information_per_dim"), per_variable("kl_per_dim"))
    options = {"ladder": ladder, "index": index, "values": values, "draw": draw}
    if env_id is None and draw == "run" and world != DEFAULT_WORLD:
        options["world"] = world
    if env_id is not None:
        options.update(env=env_id, env_kwargs=env_kwargs or {}, dims=list(dims))
    write_traversal(out, result, provenance("famarl traverse", options, None, [model]))
    where = "" if env_id is None else f" in {env_id}"
    plot_traversal(
        result,
        out.with_suffix(".png"),
        f"{model.name}: latent traversal over {format_values(values)}{where}",
        None if env_id is None else dims,
    )
    if result.frames is not None:
        plot_traversal_frames(
            result, out.with_suffix(".frames.png"), f"{model.name} in {env_id}: the end of each macro"
        )
    names = [f"({lad},{i})" for lad, i in variables]
    effects = dict(zip(names, map(float, result.effects), strict=True))

    def named(values: list[float] | None) -> dict | None:
        return None if values is None else dict(zip(names, values, strict=True))

    write_json(
        out.with_suffix(".json"),
        {
            "effects_m": effects,
            "information_nats": named(carried.information),
            "kl_nats": named(carried.kl),
            "values": values,
        },
    )
    return result, carried


@dataclass(frozen=True)
class Carried:
    """What each traversed variable carries of the training segments, as its checkpoint records it (nats; None
    where it does not: checkpoints before the information, or before either)."""

    information: list[float] | None
    kl: list[float] | None

    @property
    def best(self) -> tuple[str, list[float]] | None:
        """The information, else (older checkpoints) the KL, with its name; None when neither is recorded."""
        if self.information is not None:
            return "information", self.information
        return None if self.kl is None else ("KL", self.kl)


def format_values(values: list[float]) -> str:
    return ",".join(f"{v:g}" for v in np.asarray(values, dtype=float))


def evaluate_run(
    run: str, into: str, episodes: int, seed: int, rollouts: int, film: bool, success_return: float | None = None
) -> dict:
    """Evaluate the run folder ``run`` into the folder ``into``: ``eval.json`` (the policy acting with its mode,
    and under ``sampled`` the same numbers for the policy drawing its actions as in training), ``rollouts.png``
    (ContinuousWorld) and, with ``film``, one rendered episode. Success follows :mod:`famarl_cli.envs.success`
    (``success_return`` overrides the run's); ``success_rule`` says which rule judged it. Returns what eval.json
    holds, less provenance."""
    from famarl_cli.artifacts.runs import (
        CHECKPOINT_FILE,
        EVAL_FILE,
        FILM_FILE,
        ROLLOUTS_FILE,
        STILLS_FILE,
        read_run_file,
    )
    from famarl_cli.report.plots import plot_rollouts, save_film
    from famarl_cli.rl.evaluation import evaluate, film_episode
    from famarl_cli.rl.training import load_agent

    run_folder, into_folder = Path(run), Path(into)
    agent = load_agent(run_folder)
    result = evaluate(agent, episodes, seed, rollouts, success_return=success_return)
    sampled = evaluate(agent, episodes, seed, 0, sample=True, success_return=success_return)
    evaluation = {
        **result.metrics,
        "sampled": sampled.metrics,
        "label": agent.spec.label,
        "agent": str(agent.spec.agent),
        "env": agent.spec.env_id,
        "seed": agent.spec.seed,
        "run": str(run_folder),
        "env_steps": agent.env_steps,
        "train_wall_s": read_run_file(run_folder)["wall_s"],
    }
    into_folder.mkdir(parents=True, exist_ok=True)
    params = {
        "episodes": episodes,
        "seed": seed,
        **({} if success_return is None else {"success_return": success_return}),
    }
    prov = provenance("famarl evaluate", params, seed, [run_folder / CHECKPOINT_FILE])
    write_json(into_folder / EVAL_FILE, {**evaluation, "provenance": prov})
    if result.traces:
        title = (
            f"{agent.spec.label}, seed {agent.spec.seed}: deterministic episodes, one colour per decision "
            "(black dots: single primitive steps)"
        )
        plot_rollouts(result.traces, into_folder / ROLLOUTS_FILE, title)
    if film:
        save_film(film_episode(agent, seed), into_folder / FILM_FILE, into_folder / STILLS_FILE)
    return evaluation
