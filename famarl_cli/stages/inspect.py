"""What ``famarl inspect`` reads out of a model checkpoint: a FAVAE's shape and training, a prior's scores."""

from __future__ import annotations

from pathlib import Path


def model_rows(path: Path, schema: str) -> list[tuple[str, str]]:
    """What the FAVAE (``famarl.favae``) or prior (``famarl.prior``) checkpoint at ``path`` holds, as (name, value)
    rows."""
    if schema == "famarl.prior":
        from famarl_cli.method.prior.checkpoint import load_skills

        scores = load_skills(path).scores
        keys = ("held_out_prior_nll", "held_out_standard_nll", "held_out_closed_mse", "held_out_open_mse")
        return [(key.replace("_", " "), "n/a" if scores.get(key) is None else f"{scores[key]:.4f}") for key in keys]
    from famarl_cli.method.favae.checkpoint import load_favae

    model, payload = load_favae(path)
    config, training = model.config, payload.get("training", {})
    rows = [
        (
            "model",
            f"{config.ladders} ladders of {', '.join(map(str, config.latent_dims))} latents; actions of "
            f"{config.action_dim} values, L = {config.length}",
        )
    ]
    for key in ("beta", "c_last", "capacities"):
        if key in training:
            value = training[key]
            rows.append((key, ", ".join(f"{v:.3f}" for v in value) if isinstance(value, list) else f"{value:g}"))
    return rows
