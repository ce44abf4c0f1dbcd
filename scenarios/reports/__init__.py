"""What a person reads: text and markdown tables (:mod:`.report`), figures (:mod:`.plots`) and a
sweep's summary (:mod:`.sweep_report`)."""

__all__: list[str] = []
