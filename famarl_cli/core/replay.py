"""A step function run many times, as one CUDA graph replayed on a GPU.

A small network's training step on a GPU is hundreds of kernels of a few microseconds each; launched one by one
from Python, the launches cost more than the arithmetic. A CUDA graph records the step's kernels once and
launches them all with one call (``torch.cuda.CUDAGraph``, as in PyTorch's "whole-network capture"). On the CPU, and
where ``graph`` is off, the step simply runs.

A replayed step repeats the kernels it recorded, on the same memory: it must read what changes between calls
from device tensors it updates itself (a counter it advances, parameters it steps in place), never from a Python
value or a host tensor, and must not read device values back to the host.
"""

from __future__ import annotations

from collections.abc import Callable

import torch


class Replayed:
    """Calls ``step`` ``times`` times per call of this object. On a CUDA device (with ``graph``) the first call
    of ``step`` runs eagerly on a side stream, which warms up what a library creates on first use (cuBLAS handles,
    an optimiser's state); the second is captured and every call from then on replays the capture."""

    def __init__(self, step: Callable[[], None], device: torch.device | str, graph: bool = True) -> None:
        self.step = step
        self.device = torch.device(device)
        self.capture = graph and self.device.type == "cuda"
        self.graph: torch.cuda.CUDAGraph | None = None
        self.warmed = False

    def __call__(self, times: int = 1) -> None:
        for _ in range(times):
            if not self.capture:
                self.step()
            elif not self.warmed:
                side = torch.cuda.Stream(self.device)
                side.wait_stream(torch.cuda.current_stream(self.device))
                with torch.cuda.stream(side):
                    self.step()
                torch.cuda.current_stream(self.device).wait_stream(side)
                self.warmed = True
            else:
                if self.graph is None:
                    self.graph = torch.cuda.CUDAGraph()
                    with torch.cuda.graph(self.graph):  # records the kernels; runs nothing
                        self.step()
                self.graph.replay()
