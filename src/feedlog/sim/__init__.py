"""feedlog.sim: a fast NC interpolator simulation built from registered physical mechanisms.

Public API: `simulate(program, profile, *, mechanisms=None) -> SimResult`, `measure(result, ...)`
(the measurement model: a SimResult as a sampled, noisy `Recording`), `REGISTRY` of mechanisms.
"""

from feedlog.sim.mechanism import REGISTRY, Mechanism, mechanism_class, resolve_mechanisms
from feedlog.sim.simulate import SimResult, simulate


def __getattr__(name: str):
    # the measurement model imports feedlog.ingest: load it only when asked for
    if name in ("measure", "MeasurementModel"):
        import importlib  # noqa: PLC0415

        return getattr(importlib.import_module("feedlog.sim.measurement"), name)
    raise AttributeError(name)


__all__ = ["REGISTRY", "MeasurementModel", "Mechanism", "SimResult", "measure", "mechanism_class",
           "resolve_mechanisms", "simulate"]
