"""K replicates' parameters as one (K, P) tensor, row k replicate k's (what
:class:`~famarl_cli.core.replicate_adam.ReplicateAdam` steps), and each parameter a (K, *shape) view of it: the
layers read the rows the optimiser writes, with no copy between them."""

from __future__ import annotations

import math

import torch
from torch import nn


def size(shapes: dict[str, tuple[int, ...]]) -> int:
    """Values of one replicate."""
    return sum(math.prod(shape) for shape in shapes.values())


def views(flat: torch.Tensor, shapes: dict[str, tuple[int, ...]]) -> dict[str, torch.Tensor]:
    """Each named (K, *shape) view of ``flat`` (K, P), the shapes laid one after the other along a row."""
    named, offset = {}, 0
    for name, shape in shapes.items():
        named[name] = flat[:, offset : offset + math.prod(shape)].view(len(flat), *shape)
        offset += math.prod(shape)
    return named


def stacked(
    modules: list[nn.Module], device: torch.device | str = "cpu"
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """The parameters of K modules of one architecture as rows of one (K, P) tensor on ``device`` (filled on the CPU
    and moved in one copy), and each parameter's (K, *shape) view of it, by its name in the modules."""
    shapes = {name: tuple(value.shape) for name, value in modules[0].named_parameters()}
    flat = torch.zeros(len(modules), size(shapes))
    named = views(flat, shapes)
    with torch.no_grad():
        for k, module in enumerate(modules):
            for name, value in module.named_parameters():
                named[name][k] = value
    flat = flat.to(device)
    return flat, views(flat, shapes)


def gather(gradients: list[torch.Tensor] | tuple[torch.Tensor, ...], into: torch.Tensor) -> torch.Tensor:
    """The (K, *shape) gradients of :func:`views`' views, laid into ``into`` (K, P) where the views lie, one copy
    each: the gradient of a weight read transposed is itself transposed, where a reshape and a cat would copy it
    twice."""
    offset = 0
    for gradient in gradients:
        size = gradient[0].numel()
        into[:, offset : offset + size].view(gradient.shape).copy_(gradient)
        offset += size
    return into
