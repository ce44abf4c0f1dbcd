"""Experiments over many runs: a controller comparison (:mod:`.compare`) with every model's
prediction error (:mod:`.prediction`), grids on Ray (:mod:`.sweep`) and the paper's
reproduction (:mod:`.reproduce`)."""

__all__: list[str] = []
