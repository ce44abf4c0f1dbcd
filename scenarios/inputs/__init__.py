"""What a run is given: scenarios (:mod:`.registry`) and their TOML files (:mod:`.scenario_file`),
weather, prices, comfort and gains (:mod:`.exogenous`), measured weather and prices from CSV
files (:mod:`.measured`), and the series a run is driven by with its forecast errors
(:mod:`.series`)."""

__all__: list[str] = []
