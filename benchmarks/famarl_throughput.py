"""FaMARL's decision throughput: FAVAE decoding alone, and training with the decoder in the loop against PPO
and FiGAR on the same environment.

    python benchmarks/famarl_throughput.py [--favae data/favae/pushed-down-only.pt] [--steps 200000] [--env ID]

1. Decoding: ``Favae.decode_macro_actions`` on batches of 1 to 256 latents (one batch per rollout step of that
   many environments): macro decisions per second.
2. Training: each agent with `famarl train`'s defaults (16 environments; 16, 32, 128 decisions per environment
   per rollout for famarl, figar, ppo) for ``--steps`` environment steps on ``--env`` (the Maze unless named): env
   steps and decisions per second, and where the time goes (decoding, the rest of the rollout, PPO updates), with
   the share the env's own steps take (as many steps of one ``gym.make`` env, clocked alone): what a faster env
   could give the run at most.

The FAVAE is the default pipeline's (`dvc repro` makes it) or, for another env, one fitted on its demos
(``--env famarl/RobotHand-Reaching-v1 --favae data/robothand/macros/seed10/favae.pt``). Prints tables and writes
JSON; the Maze's entries in measured.json are ``famarl_throughput_*``, another env's carry its name.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
import torch
from common import (
    RESULTS,
    command_line,
    peak_rss_mib,
    rate,
    record,
    rounded,
    single_env_rate,
    timed,
    verdict,
    write_result,
)

from famarl_cli.core.errors import FamarlError
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.rl import Agent
from famarl_cli.rl.training import Run
from famarl_cli.stages.train import DEFAULT_ENV, TrainOptions, run_spec

BATCHES = (1, 16, 64, 256)


def decoding(favae, seconds: float) -> list[dict]:
    rows = []
    rng = np.random.default_rng(0)
    for batch in BATCHES:
        latents = itertools.cycle(rng.standard_normal((64, batch, favae.config.latent_size)).astype(np.float32))
        per_s = rate(lambda: favae.decode_macro_actions(next(latents)), batch, seconds)  # noqa: B023 (called here)
        rows.append({"batch": batch, "decisions_per_s": per_s, "ms_per_call": 1000 * batch / per_s})
    return rows


def training(agent: Agent, favae_path: Path, steps: int, env_id: str, env_rate: float) -> dict:
    """The run ``famarl train --agent AGENT --favae FAVAE_PATH --steps STEPS --env ENV_ID`` makes, trained and
    clocked; ``env_rate`` is the env's own steps per second, alone."""
    trainer = Run.start(run_spec(TrainOptions(agent=agent, favae=favae_path, steps=steps, env=env_id))).trainer
    spent = {"decoding": 0.0, "update": 0.0}

    def clocked(name, function):
        def call(*args):
            result, seconds = timed(lambda: function(*args))
            spent[name] += seconds
            return result

        return call

    trainer.members[0].mode.to_sequences = clocked("decoding", trainer.members[0].mode.to_sequences)
    trainer.update = clocked("update", trainer.update)
    _, seconds = timed(trainer.train)
    return {
        "agent": str(agent),
        "env_steps": trainer.members[0].env_steps,
        "decisions": trainer.members[0].decisions,
        "seconds": seconds,
        "env_steps_per_s": trainer.members[0].env_steps / seconds,
        "decisions_per_s": trainer.members[0].decisions / seconds,
        "decoding_s": spent["decoding"],
        "rollout_other_s": seconds - spent["decoding"] - spent["update"],
        "update_s": spent["update"],
        "env_share": trainer.members[0].env_steps / env_rate / seconds,
    }


def records(
    decode_rows: list[dict], train_rows: list[dict], command: str, env_id: str, env_rate: float
) -> dict[str, dict]:
    """measured.json's entries: training with the decoder in the loop against PPO and FiGAR, and decoding; named
    ``famarl_throughput_*`` on the Maze, with the env's name added on another."""
    trained = {row["agent"]: row for row in train_rows}
    decoded = {row["batch"]: row["decisions_per_s"] for row in decode_rows}
    ratio = trained["famarl"]["env_steps_per_s"] / trained["ppo"]["env_steps_per_s"]
    named, where = suffix(env_id), "" if env_id == DEFAULT_ENV else f" on {env_id}"
    shares = [row["env_share"] for row in trained.values()]
    # What is left to make faster once the env is as fast as it is: microseconds per env step outside its steps.
    outside = {
        f"{agent}_outside_env": 1e6 * row["seconds"] * (1 - row["env_share"]) / row["env_steps"]
        for agent, row in trained.items()
    }
    return {
        f"famarl_throughput_training{named}": {
            "what": f"FaMARL training with the FAVAE decoder in the loop (`famarl train` defaults){where}",
            "command": command,
            "measured": f"{rounded(trained['famarl']['env_steps_per_s'])} env steps/s, "
            f"{rounded(trained['famarl']['decisions_per_s'])} decisions/s; PPO "
            f"{rounded(trained['ppo']['env_steps_per_s'])}, FiGAR {rounded(trained['figar']['env_steps_per_s'])}: "
            f"FaMARL **{ratio:.1f}x** PPO's"
            + verdict(ratio >= 0.5)
            + "; the env's own steps "
            + " / ".join(f"{share:.0%}" for share in shares)
            + " of each run",
            "target": ">= 0.5x PPO's",
            "values": {
                "famarl": trained["famarl"]["env_steps_per_s"],
                "famarl_decisions": trained["famarl"]["decisions_per_s"],
                "ppo": trained["ppo"]["env_steps_per_s"],
                "figar": trained["figar"]["env_steps_per_s"],
                "famarl_over_ppo": ratio,
                "env_alone": env_rate,
                **outside,
            },
            "unit": {
                "famarl": "env steps/s",
                "famarl_decisions": "decisions/s",
                "ppo": "env steps/s",
                "figar": "env steps/s",
                "famarl_over_ppo": "x",
                "env_alone": "env steps/s",
                **dict.fromkeys(outside, "us"),
            },
            "better": {"famarl_over_ppo": "higher"},
        },
        f"famarl_throughput_decoding{named}": {
            "what": "FAVAE decoding, batched",
            "command": command,
            "measured": f"{rounded(decoded[16])} decisions/s at 16 latents per call, {rounded(decoded[64])} at 64",
            "values": {"latents_16": decoded[16], "latents_64": decoded[64]},
            "unit": "decisions/s",
        },
    }


def suffix(env_id: str) -> str:
    """What the names of ``env_id``'s results add: nothing on the Maze, ``_robothand_reaching_v1`` for
    ``famarl/RobotHand-Reaching-v1``."""
    if env_id == DEFAULT_ENV:
        return ""
    return "_" + "".join(c if c.isalnum() else "_" for c in env_id.rsplit("/", 1)[-1].lower())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--favae", type=Path, default=Path("data/favae/pushed-down-only.pt"))
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--env", default=DEFAULT_ENV, help="Env id to train on (default: the Maze)")
    parser.add_argument("--seconds", type=float, default=2.0, help="per decoding measurement")
    parser.add_argument("--out", type=Path, help="JSON to write (default: results/famarl_throughput[_<env>].json)")
    args = parser.parse_args()
    if not args.favae.is_file():
        raise SystemExit(f"error: {args.favae} not found: make it with `dvc repro favae_fit` (or pass --favae)")
    if args.steps < 1 or not args.seconds > 0:
        raise SystemExit("error: --steps must be at least 1 and --seconds above 0")
    try:  # the env, and the FAVAE's actions fitting it, before anything is timed: famarl's own one-line refusals
        Run.start(run_spec(TrainOptions(agent=Agent.FAMARL, favae=args.favae, steps=1, env=args.env)))
    except FamarlError as exc:
        raise SystemExit(f"error: {exc}") from None
    out = args.out or RESULTS / f"famarl_throughput{suffix(args.env)}.json"
    torch.set_num_threads(1)
    favae = load_favae(args.favae)[0]

    decode_rows = decoding(favae, args.seconds)
    print(f"{'latents per call':>16} {'decisions/s':>12} {'ms per call':>12}")
    for row in decode_rows:
        print(f"{row['batch']:>16} {row['decisions_per_s']:>12,.0f} {row['ms_per_call']:>12.3f}")

    env_rate = single_env_rate(args.env, args.seconds)
    agents = (Agent.FAMARL, Agent.PPO, Agent.FIGAR)
    train_rows = [training(agent, args.favae, args.steps, args.env, env_rate) for agent in agents]
    print(f"\n{args.env}: {env_rate:,.0f} env steps/s alone")
    columns = ("decoding", "rollout", "update", "(env)")
    print(f"{'agent':<8} {'env steps/s':>12} {'decisions/s':>12} " + " ".join(f"{c:>9}" for c in columns))
    for row in train_rows:
        shares = [row[k] / row["seconds"] for k in ("decoding_s", "rollout_other_s", "update_s")] + [row["env_share"]]
        cells = " ".join(f"{share:>9.0%}" for share in shares)
        print(f"{row['agent']:<8} {row['env_steps_per_s']:>12,.0f} {row['decisions_per_s']:>12,.0f} {cells}")
    rates = {row["agent"]: row["env_steps_per_s"] for row in train_rows}
    ratio = rates["famarl"] / rates["ppo"]
    print(f"famarl / ppo env steps per second: {ratio:.2f}x   peak RSS {peak_rss_mib():.0f} MiB")
    result = {"favae": str(args.favae), "env": args.env, "env_steps_per_s_alone": env_rate, "steps": args.steps}
    write_result(out, {**result, "ratio": ratio, "decoding": decode_rows, "training": train_rows})
    for name, entry in records(
        decode_rows, train_rows, command_line(__file__, parser, args), args.env, env_rate
    ).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
