"""A BOPTEST sweep's test case and its training data, recorded on the emulator."""

from __future__ import annotations

from typing import TYPE_CHECKING

from scenarios.experiments.sweep.grid import ModelKey

if TYPE_CHECKING:
    import pandas as pd

    from scenarios.running.boptest_loop import BoptestScenario

__all__ = ["boptest_training_data"]


def boptest_training_data(key: ModelKey, boptest_url: str | None = None) -> pd.DataFrame:
    """The emulator's training data of a BOPTEST model ``key``: ``key.train_days`` days on the
    days nearest its test period, as ``compare`` and ``simulate --test-period`` take them
    (:func:`scenarios.running.boptest_loop.boptest_data`), seed ``key.seed``; ``boptest_url``
    the server when the scenario file names none."""
    from scenarios.running.boptest_loop import DATA_FIRST_DAY, boptest_data

    chosen = _boptest_chosen(key.scenario, boptest_url)
    first_day = (
        DATA_FIRST_DAY if key.test_period is None
        else chosen.settings.points.data_first_day(key.test_period, float(key.train_days))
    )
    return boptest_data(chosen, days=key.train_days, seed=key.seed, first_day=first_day)


def _boptest_chosen(scenario: str, boptest_url: str | None) -> BoptestScenario:
    from scenarios.running.boptest_loop import boptest_scenario

    chosen = boptest_scenario(scenario)
    if chosen.settings.url is None and boptest_url is not None:
        chosen = boptest_scenario(scenario, url=boptest_url)
    return chosen


