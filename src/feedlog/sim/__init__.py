"""feedlog.sim: a fast NC interpolator simulation built from registered physical mechanisms.

Public API: `simulate(program, profile, *, mechanisms=None) -> SimResult`, `measure(result, ...)`
(the measurement model: a SimResult as a sampled, noisy `Recording`), `REGISTRY` of mechanisms.
"""

from feedlog.sim.measurement import MeasurementModel, measure
from feedlog.sim.mechanism import REGISTRY, Mechanism, mechanism_class, resolve_mechanisms
from feedlog.sim.simulate import SimResult, simulate

__all__ = ["REGISTRY", "MeasurementModel", "Mechanism", "SimResult", "measure", "mechanism_class",
           "resolve_mechanisms", "simulate"]
