"""famarl: macro-action reinforcement learning over disentangled action-sequence latents (FaMARL).

Importing the package registers famarl's environments with gymnasium (``famarl/ContinuousWorld-Maze-v0`` and its
peers, :mod:`famarl_cli.envs`), as gymnasium 1.x users expect of an env package: ``import famarl_cli`` and then
``gymnasium.make(id)``, or ``gymnasium.register_envs(famarl_cli)`` where a linter would drop an unused import.
"""

from importlib.metadata import PackageNotFoundError, version

from famarl_cli.core.reproducibility import apply_environment

# Before anything below loads numpy or torch: their kernels are chosen when they load.
apply_environment()

try:
    __version__ = version("famarl")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

# After apply_environment: the envs load numpy.
from famarl_cli import envs  # noqa: E402, F401
