"""famarl: macro-action reinforcement learning over disentangled action-sequence latents (FaMARL)."""

from importlib.metadata import PackageNotFoundError, version

from famarl_cli.core.reproducibility import apply_environment

# Before anything below loads numpy or torch: their kernels are chosen when they load.
apply_environment()

try:
    __version__ = version("famarl")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"
