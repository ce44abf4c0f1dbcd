"""Copying and pickling a ``torch.Generator`` without corrupting Python's ``None``.

torch's own ``Generator.__reduce__`` (up to at least torch 2.13) puts ``None`` into the state
tuple it returns without taking a reference to it (pytorch/pytorch#188032). On Python 3.11,
where ``None`` is reference-counted, every ``copy.deepcopy`` or ``pickle.dumps`` of a CPU
generator therefore takes one reference from ``None`` for good; a fleet's planners copy their
controllers (and so their generators) every step, and after some hundred thousand copies the
interpreter aborts with ``Fatal Python error: none_dealloc``.

Importing this module registers, in :mod:`copyreg`, a reduction of ``torch.Generator`` that
keeps its device, seed, offset and state and holds ``None`` properly; ``copy.deepcopy`` and
``pickle`` consult :mod:`copyreg` before the type's own ``__reduce__``. A copy draws the same
numbers as the original would from the moment it was copied.
"""

from __future__ import annotations

import copyreg
from typing import Any

import torch

__all__ = ["generator_from_state", "reduce_generator"]


def generator_from_state(
    device: torch.device, initial_seed: int, offset: int | None, state: torch.Tensor
) -> torch.Generator:
    """A new generator on ``device`` whose seed, offset (None on the CPU) and state are
    those given (the inverse of :func:`reduce_generator`)."""
    generator = torch.Generator(device=device)
    generator.manual_seed(initial_seed)
    if offset is not None:
        generator.set_offset(offset)
    generator.set_state(state)
    return generator


def reduce_generator(generator: torch.Generator) -> tuple[Any, tuple[Any, ...]]:
    """The pickle reduction of ``generator``: :func:`generator_from_state` and its arguments."""
    offset = None if generator.device.type == "cpu" else generator.get_offset()
    return generator_from_state, (generator.device, generator.initial_seed(), offset, generator.get_state())


copyreg.pickle(torch.Generator, reduce_generator)
