"""The named choices of the modelling layer: architectures and training recipes.

They live in light modules (no torch, no pandas) so that the CLI can offer them as choices
and print its help without loading the libraries that implement them. The architectures are
those of the registry (:mod:`pinn_mpc.models.registry`).
"""

from __future__ import annotations

from pinn_mpc.models.registry import (
    ALL_ARCHS,
    ARCHS,
    ARX,
    AUTO,
    COMPARED_ARCHS,
    DEFAULT_ARCH,
    MODEL_CHOICES,
    PHYSICS_ARX,
    TRAIN_CHOICES,
)

__all__ = [
    "ALL_ARCHS",
    "ARCHS",
    "AUTO",
    "ARX",
    "COMPARED_ARCHS",
    "DEFAULT_ARCH",
    "MODEL_CHOICES",
    "PHYSICS_ARX",
    "RECIPES",
    "RESIDUALS",
    "TRAIN_CHOICES",
]

#: Physics residuals of the training loss (:class:`pinn_mpc.training.TrainConfig`).
RESIDUALS = ("exact", "finite_difference")
#: Per recipe: epochs, batch size, initial and final learning rate, default lambda
#: (:mod:`pinn_mpc.training`).
RECIPES: dict[str, dict[str, float]] = {
    "paper": {"epochs": 75, "batch_size": 2048, "lr": 1e-3, "lr_final": 1e-3, "lam": 1.0},
    "converged": {"epochs": 60, "batch_size": 512, "lr": 1e-2, "lr_final": 1e-4, "lam": 1.0},
    "long": {"epochs": 150, "batch_size": 512, "lr": 1e-2, "lr_final": 1e-4, "lam": 1.0},
}
