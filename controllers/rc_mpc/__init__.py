"""MPC on RC parameters: the problem and controller shell (:mod:`.problem`), its CasADi
(:mod:`.casadi`) and OSQP (:mod:`.osqp`, on the OSQP data of :mod:`.qp`) solvers, and the
perfect-knowledge references (:mod:`.references`). Import from the modules: each solver loads only its own library."""

__all__: list[str] = []  # nothing here: each solver loads only its own library
