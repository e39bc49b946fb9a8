"""Every default has one source: ``famarl train``'s options are the settings of PPO and of a run
(:mod:`famarl_cli.rl.options`), PPOConfig and RunSpec take their defaults from them, and ``famarl sweep``'s options
are a declaration too."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import re
from pathlib import Path

import pytest

from famarl_cli.core.declare import declared
from famarl_cli.core.errors import UsageError
from famarl_cli.rl import Agent, agent_defaults
from famarl_cli.rl.options import PPOOptions, RunOptions
from famarl_cli.stages.train import DEFAULT_ENV, TrainOptions, run_spec


@pytest.mark.parametrize("agent", list(Agent))
def test_famarl_train_left_alone_is_the_settings_own_defaults(agent):
    """A run of ``famarl train --agent A`` with nothing else given is PPOConfig's and RunSpec's defaults, but for
    what depends on the agent: a default declared again with another value, in the options or in a dataclass,
    fails here. ``PPOConfig()`` is ``famarl train --agent ppo``'s."""
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.spec import RunSpec

    spec = run_spec(TrainOptions(agent=agent, favae=Path("f.pt")))
    own = agent_defaults(agent)
    ppo = {name: value for name, value in own.items() if name in {f.name for f in dataclasses.fields(PPOConfig)}}
    run = {name: value for name, value in own.items() if name not in ppo}
    favae = "f.pt" if agent.decodes_macros else None
    assert spec == RunSpec(DEFAULT_ENV, agent, 0, PPOConfig(**ppo), favae=favae, label=spec.label, **run)
    if agent == Agent.PPO:
        assert spec.ppo == PPOConfig()


def _defaults(cls: type) -> dict[str, ast.expr]:
    """The expression each field of the dataclass ``cls`` takes its default from, as its source writes it."""
    body = ast.parse(inspect.getsource(cls)).body[0].body
    return {node.target.id: node.value for node in body if isinstance(node, ast.AnnAssign) and node.value is not None}


def _literal(node: ast.expr) -> bool:
    """A value written out (``3e-4``, ``-1``, ``MacroDecoder.OPEN``), not one taken from a declaration."""
    if isinstance(node, ast.UnaryOp):
        return _literal(node.operand)
    return isinstance(node, ast.Constant) or (isinstance(node, ast.Attribute) and node.attr.isupper())


def test_the_options_famarl_train_refuses_for_other_agents_are_those_their_help_gives_agents():
    """An option whose help opens with the agents it is for (``hybrid: ...``) is refused for the others
    (AGENT_OPTIONS): a new one missing there would be accepted and ignored. --prior and --loop, refused by the
    options themselves (--loop closed needs --prior), --favae, whose help names its agents in brackets, and
    --macro-discount, which every agent but PPO uses (its decisions are one step), are checked on their own."""
    from famarl_cli.stages.train import AGENT_OPTIONS, MACRO_AGENTS

    options = {option.name: option for option in declared(TrainOptions)}
    agent = "|".join(Agent)
    helped = {
        name: tuple(Agent(agent) for agent in opening[1].split(", "))
        for name, option in options.items()
        if (opening := re.match(rf"((?:{agent})(?:, (?:{agent}))*): ", option.help))
    }
    helped.pop("agent")  # its help opens with what each agent searches
    assert helped.pop("prior") == helped.pop("loop") == MACRO_AGENTS
    on_their_own = ("favae", "macro_discount")
    assert helped == {name: agents for name, agents in AGENT_OPTIONS.items() if name not in on_their_own}
    assert AGENT_OPTIONS["favae"] == MACRO_AGENTS and "(famarl and hybrid)" in options["favae"].help
    assert set(AGENT_OPTIONS["macro_discount"]) == set(Agent) - {Agent.PPO}
    with pytest.raises(UsageError, match="--prior goes with --agent famarl or hybrid, not ppo"):
        TrainOptions(agent=Agent.PPO, prior=Path("p.pt"))


def test_no_option_default_is_written_again_in_the_settings():
    """PPOConfig's and RunSpec's fields that a ``famarl train`` option with a default sets take that default from
    the option's declaration, never as a literal of their own; and TrainOptions does not declare them again."""
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.spec import RunSpec
    from famarl_cli.stages.train import setting_options

    by_flag = {option.flag: option for option in declared(TrainOptions)}
    set_by = {setting: by_flag[flag] for setting, flag in setting_options().items() if flag in by_flag}
    written = {
        **{name: node for name, node in _defaults(RunSpec).items()},
        **{f"ppo.{name}": node for name, node in _defaults(PPOConfig).items()},
    }
    checked = [setting for setting, option in set_by.items() if option.default is not None and setting in written]
    assert {"ppo.learning_rate", "ppo.normalize_obs", "ppo.epochs", "prior_weight", "loop"} <= set(checked)
    assert [setting for setting in checked if _literal(written[setting])] == []

    shared = {f.name for f in dataclasses.fields(PPOOptions)} | {f.name for f in dataclasses.fields(RunOptions)}
    assert not shared & set(TrainOptions.__annotations__)


def test_sweep_s_options_are_its_declaration():
    from famarl_cli.cli import app
    from famarl_cli.cli.derived import click_command
    from famarl_cli.cli.sweep import SweepOptions

    params = {param.name: param for param in click_command(app).commands["sweep"].params}
    for option in declared(SweepOptions):
        assert option.flag in params[option.name].opts or option.argument
        if option.default is not dataclasses.MISSING:
            assert params[option.name].default == option.default, option.name
