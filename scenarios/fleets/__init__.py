"""Many buildings: a fleet's closed loop (:mod:`.fleet`), a fleet under a power cap
(:mod:`.aggregator`) and its convex reference (:mod:`.reference`), a fleet planner split across
Ray workers (:mod:`.partitions`), and one model per building (:mod:`.training`)."""

__all__: list[str] = []
