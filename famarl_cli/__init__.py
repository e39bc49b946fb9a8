"""famarl: macro-action reinforcement learning over disentangled action-sequence latents (FaMARL)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("famarl")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"
