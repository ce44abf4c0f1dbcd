"""The named choices of the modelling layer: architectures and training recipes.

They live in this light module (no torch, no pandas) so that the CLI can offer them as choices
and print its help without loading the libraries that implement them; :mod:`pinn_mpc.models`
and :mod:`pinn_mpc.training` take them from here.
"""

from __future__ import annotations

__all__ = ["ALL_ARCHS", "ARCHS", "DEFAULT_ARCH", "RECIPES", "RESIDUALS"]

#: The paper's three learned-model architectures (:mod:`pinn_mpc.models`).
ARCHS = ("mlp", "physreg", "physnet")
#: Every architecture: the paper's and the hybrid this package recommends for control.
ALL_ARCHS = (*ARCHS, "hybrid")
DEFAULT_ARCH = "hybrid"
#: Physics residuals of the training loss (:class:`pinn_mpc.training.TrainConfig`).
RESIDUALS = ("exact", "finite_difference")
#: Per recipe: epochs, batch size, initial and final learning rate, default lambda
#: (:mod:`pinn_mpc.training`).
RECIPES: dict[str, dict[str, float]] = {
    "paper": {"epochs": 75, "batch_size": 2048, "lr": 1e-3, "lr_final": 1e-3, "lam": 1.0},
    "converged": {"epochs": 60, "batch_size": 512, "lr": 1e-2, "lr_final": 1e-4, "lam": 1.0},
}
