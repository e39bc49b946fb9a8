"""The package's shape holds: folders are layers and no import runs back up (not even one inside a function), the
extension points say what they need, options are declared once, and checkpoints explain themselves."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

from famarl_cli.core.errors import ArtifactError, UsageError

PACKAGE = Path(__file__).parents[1] / "famarl_cli"
FLOORS = {
    "__main__": 8,
    "cli": 7,
    "stages": 6,
    "wrappers": 6,
    "rl": 5,
    "report": 5,
    "method": 4,
    "sweep": 3,
    "experts": 2,
    "artifacts": 2,
    "__init__": 1.5,
    "envs": 1,
    "core": 0,
}
"""Each room of famarl_cli (a folder, or a module at the top) and its floor: a room imports only rooms below it
(docs/design.md). The package's face (famarl_cli/__init__.py: its version, the environment set before numpy loads,
and the envs registered with gymnasium) stands just above the envs: it imports core and envs, and every room from
artifacts up may import it."""


def room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def imports() -> list[tuple[str, str, int]]:
    """(importing module, imported module, line) for every import of famarl_cli inside famarl_cli."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts).removesuffix(".__init__")
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("famarl_cli"):
                targets = [node.module]
                if node.module == "famarl_cli":  # a room imported by name, or the face's version
                    rooms = [
                        a.name
                        for a in node.names
                        if (PACKAGE / a.name).is_dir() or (PACKAGE / f"{a.name}.py").is_file()
                    ]
                    targets = [f"famarl_cli.{name}" for name in rooms] or ["famarl_cli"]
                found += [(module, target, node.lineno) for target in targets]
            elif isinstance(node, ast.Import):
                found += [(module, a.name, node.lineno) for a in node.names if a.name.startswith("famarl_cli")]
    return found


def test_every_room_has_a_floor():
    rooms = {room(".".join(p.relative_to(PACKAGE.parent).with_suffix("").parts)) for p in PACKAGE.rglob("*.py")}
    assert rooms <= set(FLOORS), f"rooms without a floor: {sorted(rooms - set(FLOORS))}"


def test_no_import_runs_back_up():
    upward = [
        f"{source}:{line} imports {target}"
        for source, target, line in imports()
        if room(source) != room(target) and FLOORS[room(target)] >= FLOORS[room(source)]
    ]
    assert not upward, "\n".join(upward)


CLI_ROOMS = {"cli", "stages", "sweep", "artifacts", "core", "__init__"}
"""What the command line imports (and famarl_cli's version): it parses options and prints, the stages work."""


def test_the_command_line_imports_only_stages_sweep_artifacts_and_core():
    reached = [
        f"{source}:{line} imports {target}"
        for source, target, line in imports()
        if room(source) == "cli" and room(target) not in CLI_ROOMS
    ]
    assert not reached, "\n".join(reached)


def test_reading_artifacts_and_declarations_does_not_load_torch():
    import subprocess
    import sys

    code = (
        "import sys, famarl_cli.artifacts.traversal, famarl_cli.stages.method, famarl_cli.stages.macros, "
        "famarl_cli.stages.train, famarl_cli.stages.prior, famarl_cli.method.traversal, famarl_cli.sweep.plan, "
        "famarl_cli.artifacts.runs, famarl_cli.cli; "
        "print('torch' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout == "False\n"


def test_every_command_option_is_its_declaration():
    """The typer command is derived from the declaration: names, defaults and bounds are the same objects."""
    import typer

    from famarl_cli.cli import app
    from famarl_cli.core.declare import declared
    from famarl_cli.stages.demos import DemosOptions
    from famarl_cli.stages.evaluate import EvaluateOptions
    from famarl_cli.stages.method import CalibrateOptions, FitOptions, SegmentOptions, TraverseOptions
    from famarl_cli.stages.prior import PriorFitOptions
    from famarl_cli.stages.train import TrainOptions

    commands = typer.main.get_command(app).commands
    for name, options in (
        ("train", TrainOptions),
        ("segment", SegmentOptions),
        ("traverse", TraverseOptions),
        ("demos", DemosOptions),
        ("evaluate", EvaluateOptions),
        ("favae calibrate", CalibrateOptions),
        ("favae fit", FitOptions),
        ("prior fit", PriorFitOptions),
    ):
        command = commands[name.split()[0]]
        if " " in name:
            command = command.commands[name.split()[1]]
        params = {param.name: param for param in command.params}
        for option in declared(options):
            param = params[option.name]
            assert option.flag in param.opts
            if option.parse is None and option.default is not None and not isinstance(option.default, list):
                assert param.default == option.default, (name, option.name)


def test_beta_is_declared_once_and_reaches_every_command():
    from famarl_cli.cli import app
    from famarl_cli.cli.derived import parse_options
    from famarl_cli.method.favae import FitChoices
    from famarl_cli.stages.macros import MacrosConfig, MacrosOptions
    from famarl_cli.stages.method import FitOptions

    default = FitChoices().beta
    assert FitOptions().beta == MacrosConfig(demos=Path("d.h5")).beta == default
    assert parse_options(app, "macros", MacrosOptions, ["--demos", "d.h5"])["beta"] == default


def test_a_sweep_gives_typed_values_to_its_jobs():
    from famarl_cli.cli.sweep import plan

    jobs = plan("macros", ["--demos", "d.h5", "--epochs", "3"], "0-1", ["beta=0.5,2"], None)
    configs = {(job.config["seed"], job.config["beta"]) for job in jobs}
    assert configs == {(0, 0.5), (1, 0.5), (0, 2.0), (1, 2.0)}
    assert all(isinstance(seed, int) and isinstance(beta, float) for seed, beta in configs)
    assert {job.runner for job in jobs} == {"famarl_cli.stages.macros:run_jobs"}
    # the replicates of one beta may share a batch, those of another beta not
    assert all(job.batched for job in jobs) and len({job.group for job in jobs}) == 2
    with pytest.raises(UsageError, match="--beta"):
        plan("macros", ["--demos", "d.h5"], "0", ["beta=-1"], None)
    # a yes/no option takes its axis by click's reading of yes/no; anything else is one usage error
    runs = plan("train", ["--agent", "ppo"], "0", ["normalize=yes,no"], None)
    assert [job.config["spec"]["ppo"]["normalize_obs"] for job in runs] == [True, False]
    with pytest.raises(UsageError, match="normalize=maybe"):
        plan("train", ["--agent", "ppo"], "0", ["normalize=maybe"], None)


def test_every_sweepable_runner_resolves_to_its_function():
    import famarl_cli.cli  # noqa: F401 - the commands register what a sweep runs of each
    from famarl_cli.stages.demos import DemosOptions
    from famarl_cli.stages.macros import MacrosConfig
    from famarl_cli.stages.prior import PriorFitOptions
    from famarl_cli.stages.train import TrainOptions
    from famarl_cli.sweep.registry import SWEEPABLE
    from famarl_cli.sweep.worker import name_of, resolve

    examples = {
        "demos": DemosOptions(),
        "macros": MacrosConfig(demos=Path("d.h5")),
        "train": TrainOptions(favae=Path("f.pt")),
        "prior": PriorFitOptions(),
    }
    assert set(SWEEPABLE) == set(examples)
    for command, sweepable in SWEEPABLE.items():
        fields = {f.name for f in dataclasses.fields(sweepable.options)}
        values = {k: v for k, v in dataclasses.asdict(examples[command]).items() if k in fields}
        recipe = sweepable.make(sweepable.options(**values))
        assert resolve(name_of(recipe.runner)) is recipe.runner


def test_a_sweepable_names_only_options_its_command_has():
    from famarl_cli.stages.train import TrainOptions
    from famarl_cli.sweep.registry import sweepable

    with pytest.raises(TypeError, match="--no-such"):
        sweepable("train", TrainOptions, owned=("--no-such",))


def test_each_row_of_replicate_adam_is_torch_adam_with_its_own_rate_and_survives_a_round_trip():
    from famarl_cli.core.replicate_adam import ReplicateAdam

    torch.manual_seed(0)
    start = torch.randn(3, 50)
    ours = start.clone()
    adam = ReplicateAdam(ours, lr=3e-3, eps=1e-5)
    adam.set_lr([3e-3, 1e-2, 3e-4])
    references = [torch.nn.Parameter(row.clone()) for row in start]
    theirs = [torch.optim.Adam([p], lr=lr, eps=1e-5) for p, lr in zip(references, adam.lr, strict=True)]

    def gradient(values, step):
        return torch.sin(torch.arange(50.0) * (step + 1)) * (1 + values.abs())

    for step in range(20):
        if step == 10:  # row 1 continues in a fresh optimiser from its saved state
            saved = adam.state_dict(1)
            adam = ReplicateAdam(ours, lr=1.0, eps=1e-5)
            for row, state in ((0, None), (1, saved), (2, None)):
                adam.load_state_dict(state or {"lr": theirs[row].param_groups[0]["lr"], "steps": 0}, row)
            ours[0], ours[2] = references[0].detach(), references[2].detach()
            theirs[0] = torch.optim.Adam([references[0]], lr=3e-3, eps=1e-5)
            theirs[2] = torch.optim.Adam([references[2]], lr=3e-4, eps=1e-5)
        adam.step(torch.stack([gradient(row, step) for row in ours]))
        for p, optimiser in zip(references, theirs, strict=True):
            p.grad = gradient(p.detach(), step)
            optimiser.step()
        for row, p in zip(ours, references, strict=True):
            torch.testing.assert_close(row, p.detach(), rtol=1e-6, atol=1e-7)
    assert adam.state_dict(1)["steps"] == 20 and adam.state_dict(0)["steps"] == 10


def test_gradient_clip_matches_torch_for_each_replicate_alone():
    from famarl_cli.rl.ppo import clip_rows

    # Two replicates: one far above the limit, one below.
    rows = torch.stack([torch.linspace(-1, 2, 30) * 10.0, torch.linspace(-1, 2, 30) * 0.01])
    clipped = clip_rows(rows.clone(), 0.5)
    for k, row in enumerate(rows):
        parameter = torch.nn.Parameter(torch.zeros(30))
        parameter.grad = row.clone()
        torch.nn.utils.clip_grad_norm_([parameter], max_norm=0.5)
        torch.testing.assert_close(clipped[k], parameter.grad, rtol=0, atol=1e-7)
        assert float(clipped[k].norm()) <= 0.5 + 1e-6


def test_a_policy_checkpoint_carries_its_layout_and_refuses_another_network():
    from famarl_cli.rl.policy import ActorCritic

    policy, other = ActorCritic(4, 2, 0, 16), ActorCritic(4, 3, 0, 16)
    state = policy.state_dict()
    assert dict(state["layout"])["w_mean"] == [16, 2] and state["flat"].numel() == policy.flat.numel()
    with pytest.raises(ArtifactError, match="does not fit"):
        other.load_state_dict(state)
    swapped = {**state, "layout": state["layout"][::-1]}
    with pytest.raises(ArtifactError, match="layout"):
        policy.load_state_dict(swapped)
    del state["layout"]  # a checkpoint from before the layout was stored still loads by its size
    policy.load_state_dict(state)


def test_an_old_run_checkpoint_is_one_line(tmp_path):
    from famarl_cli.artifacts.checkpoints import save_checkpoint
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, CHECKPOINT_SCHEMA, read_run_checkpoint

    state = {"trainer": {"policy": {"w1": torch.zeros(2)}}, "mode": {}, "status": {}}
    save_checkpoint(tmp_path / CHECKPOINT_FILE, CHECKPOINT_SCHEMA, 1, {}, {"w1": torch.zeros(2)}, {}, state)
    with pytest.raises(ArtifactError, match="version 1 run checkpoint.*train the run again"):
        read_run_checkpoint(tmp_path)
    save_checkpoint(tmp_path / CHECKPOINT_FILE, CHECKPOINT_SCHEMA, 2, {}, {"flat": torch.zeros(2)}, {}, state)
    with pytest.raises(ArtifactError, match="lacks optimizer"):
        read_run_checkpoint(tmp_path)


def test_the_traversal_world_is_named_not_guessed():
    from famarl_cli.envs import WORLDS, world_of
    from famarl_cli.method.traversal import run_macro_actions

    assert world_of("famarl/RobotHand-Reaching-v0") == "robot-hand"
    assert world_of("famarl/ContinuousWorld-Maze-v0") == "continuous-world" and world_of("Pendulum-v1") is None
    four = np.zeros((1, 5, 4))
    with pytest.raises(UsageError, match="4-dimensional actions and the continuous-world world takes 2"):
        run_macro_actions(four, np.array([5]))
    assert run_macro_actions(four, np.array([5]), "robot-hand").shape == (1, 6, 2)
    assert set(WORLDS) == {"continuous-world", "robot-hand"}


def test_every_name_the_api_page_imports_imports():
    """docs/api.md's imports, alone (the examples run in the slow tier): the page's public names and
    famarl_cli.wrappers are where the page says."""
    import re

    page = (PACKAGE.parent / "docs" / "api.md").read_text()
    lines = [line for line in page.splitlines() if re.match(r"from famarl_cli[.\w]* import ", line)]
    assert any("famarl_cli.wrappers" in line for line in lines) and len(lines) > 10
    for line in lines:
        exec(line, {})  # noqa: S102


def test_evaluating_or_resuming_a_run_with_an_old_checkpoint_is_one_line(tmp_path):
    from cli_helpers import famarl, one_line_error

    from famarl_cli.artifacts.checkpoints import save_checkpoint
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, CHECKPOINT_SCHEMA

    run = tmp_path / "run"
    trained = famarl("train", "--agent", "ppo", "--steps", 64, "--n-envs", 1, "--n-steps", 64, "--out", run)
    assert trained.exit_code == 0, trained.output
    old = {"trainer": {"policy": {"w1": torch.zeros(2)}}, "mode": {}, "status": {"wall_s": 1.0}}
    save_checkpoint(run / CHECKPOINT_FILE, CHECKPOINT_SCHEMA, 1, {}, {"w1": torch.zeros(2)}, {}, old)
    for args in (("evaluate", "--run", run, "--no-film", "--episodes", 1), ("train", "--resume", "--out", run)):
        one_line_error(famarl(*args), 1, "version 1 run checkpoint")


def test_traversing_in_a_world_of_another_action_size_is_one_line_and_writes_nothing(favae_file, tmp_path):
    from cli_helpers import famarl, one_line_error

    out = tmp_path / "traverse" / "t.h5"
    one_line_error(
        famarl("traverse", "--favae", favae_file, "--world", "robot-hand", "--out", out),
        2,
        "decodes 2-dimensional actions and the robot-hand world takes 4",
    )
    assert not out.parent.exists() or not list(out.parent.iterdir())
    assert famarl("traverse", "--favae", favae_file, "--world", "moon", "--out", out).exit_code == 2
