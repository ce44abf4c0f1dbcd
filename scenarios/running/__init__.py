"""Running one closed loop: the loop engine (:mod:`.engine`), a controller on a scenario
(:mod:`.closed_loop`), training data (:mod:`.datagen`), the Gymnasium face (:mod:`.gym_env`),
controllers by name (:mod:`.factory`), KPIs (:mod:`.kpis`), work sized before it starts
(:mod:`.budget`) and Ray, where work runs across processes (:mod:`.ray_engine`)."""

__all__: list[str] = []
