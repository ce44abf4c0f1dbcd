"""What a reproduction runs: :class:`ReproduceConfig`."""

from __future__ import annotations

from dataclasses import dataclass

from pinn_mpc.choices import RECIPES

__all__ = ["ReproduceConfig"]


@dataclass(frozen=True, kw_only=True)
class ReproduceConfig:
    """What to run. ``epochs=None`` means the training recipe's value.

    ``train_days`` are the training sizes of experiment 2 (the first N days of one simulated
    training set of ``max(all sizes)`` days); ``horizon_days`` the sizes of experiment 3 and
    ``validation_days`` that of experiment 1, all trained once per architecture.
    ``size_horizons`` are the horizons [steps] of experiment 2, ``horizons`` those of
    experiment 3. The experiments are repeated on each of ``also_scenarios`` (default the
    simulated ``cold_storage``, where the paper ran experiments 2-3 on real data), each in a
    subdirectory of the output named after it.
    """

    seeds: int = 20
    epochs: int | None = None
    recipe: str = "converged"
    depth: int = 8
    validation_days: int = 120
    train_days: tuple[int, ...] = (15, 30, 45, 60, 90, 120)
    size_horizons: tuple[int, int] = (6, 24)
    horizon_days: tuple[int, int] = (30, 90)
    horizons: tuple[int, ...] = (1, 6, 12, 24, 36, 48)
    test_days: int = 5
    train_seed: int = 0
    test_seed: int = 1
    scenario: str = "paper_household"
    also_scenarios: tuple[str, ...] = ("cold_storage",)

    def __post_init__(self) -> None:
        from scenarios.inputs.scenario_file import get_scenario

        for name in (self.scenario, *self.also_scenarios):
            get_scenario(name)  # an unknown name fails here, before any work
        if self.seeds < 1:
            raise ValueError(f"reproduce: seeds must be >= 1, got {self.seeds}")
        if self.epochs is not None and self.epochs < 1:
            raise ValueError(f"reproduce: epochs must be >= 1, got {self.epochs}")
        if self.recipe not in RECIPES:
            raise ValueError(
                f"reproduce: unknown recipe {self.recipe!r}; choose one of {', '.join(RECIPES)}"
            )
        sizes = {self.validation_days, *self.train_days, *self.horizon_days}
        if not self.train_days or min(sizes) < 1:
            raise ValueError(
                f"reproduce: training sizes must be whole days >= 1, got {sorted(sizes)}"
            )
        if not self.horizons or min(self.horizons + self.size_horizons) < 1:
            raise ValueError(
                f"reproduce: horizons must be >= 1 step, got {self.horizons} and "
                f"{self.size_horizons}"
            )
        longest = max(self.horizons + self.size_horizons)
        if self.test_days * 48 < self.depth + 2 + longest:
            raise ValueError(
                f"reproduce: {self.test_days} test days are too short for depth {self.depth} "
                f"and a {longest}-step horizon; give more test days"
            )

    @classmethod
    def quick(cls, seeds: int | None = None) -> ReproduceConfig:
        """A reduced run: 3 seeds, 40 epochs, 15/60/120 days, 4 horizons."""
        return cls(
            seeds=seeds or 3,
            epochs=40,
            train_days=(15, 60, 120),
            horizon_days=(15, 120),
            horizons=(1, 6, 24, 48),
        )

    def sizes(self) -> list[int]:
        """Every training size [days] any experiment needs, ascending."""
        return sorted({self.validation_days, *self.train_days, *self.horizon_days})

    def eval_horizons(self) -> list[int]:
        """Every horizon [steps] any experiment needs, ascending."""
        return sorted({*self.horizons, *self.size_horizons})
