"""Model registry (`MODELS`, a `feedlog.registry.Registry`): name -> model class, each with a config
dataclass checked in `__post_init__`.

A model registers itself with `@register_model`; `make_model("bilstm-block", preset="quick", hidden=32)`
builds one. Presets are named overrides of a config's defaults (`quick` is sized for the demo).
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from torch import nn

from feedlog.errors import ModelError
from feedlog.registry import Registry
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import Normaliser, base_time, planner_inputs, profile_constants, raw_columns

PRESETS = ("full", "quick")


@dataclass(frozen=True)
class ModelConfig:
    """What every model's training shares: seed, optimiser, early stopping on a validation tail."""

    seed: int = 0
    epochs: int = 200
    lr: float = 0.005
    batch_size: int = 32
    patience: int = 20
    val_fraction: float = 0.2

    # preset name -> field overrides
    presets: ClassVar[dict[str, dict[str, Any]]] = {}

    def __post_init__(self) -> None:
        if self.epochs < 1 or self.batch_size < 1 or self.patience < 1:
            raise ModelError(f"{type(self).__name__}: epochs, batch_size and patience must be >= 1, got "
                             f"{self.epochs}, {self.batch_size}, {self.patience}")
        if not self.lr > 0:
            raise ModelError(f"{type(self).__name__}: lr must be > 0, got {self.lr}")
        if not 0 <= self.val_fraction < 1:
            raise ModelError(f"{type(self).__name__}: val_fraction must be in [0, 1), got {self.val_fraction}")

    def to_dict(self) -> dict[str, Any]:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelConfig:
        names = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - set(names))
        if unknown:
            raise ModelError(f"{cls.__name__}: unknown config field(s) {', '.join(unknown)}; "
                             f"known: {', '.join(names)}")
        values = {k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()}
        return cls(**values)


@dataclass
class TablePrediction:
    """A model's answer for one program: per-block durations (None for whole-program models) and the total."""

    cycle_time_s: float
    durations_s: np.ndarray | None = None
    notes: list[str] = dataclasses.field(default_factory=list)


class Model(abc.ABC):
    """A learner: `fit` on training tables, `predict` a program's block table."""

    name: ClassVar[str]
    config_class: ClassVar[type[ModelConfig]] = ModelConfig
    description: ClassVar[str] = ""

    def __init__(self, config: ModelConfig | None = None) -> None:
        config = config if config is not None else self.config_class()
        if not isinstance(config, self.config_class):
            raise ModelError(f"model {self.name!r} needs a {self.config_class.__name__}, got {type(config).__name__}")
        self.config = config
        self.norms: dict[str, Normaliser] = {}
        self.nets: dict[str, nn.Module] = {}
        self.constants: dict[str, float] = {}
        self.params: dict[str, Any] = {}
        self.fingerprint = ""
        self.report: dict[str, Any] = {}

    # -- what subclasses provide -----------------------------------------------------------------

    @property
    @abc.abstractmethod
    def inputs(self) -> tuple[str, ...]:
        """Every input column the networks read (derived names allowed, see features.py)."""

    @abc.abstractmethod
    def build_nets(self) -> None:
        """Create `self.nets` from config and params (before loading weights or training)."""

    @abc.abstractmethod
    def fit(self, tables: Sequence[ProgramTable], *, progress: bool = True) -> None:
        """Train on the tables' measured block times."""

    @abc.abstractmethod
    def predict(self, table: ProgramTable) -> TablePrediction:
        """Predict one program's block table (no `duration_s` needed)."""

    # -- shared ----------------------------------------------------------------------------------

    @property
    def required_columns(self) -> list[str]:
        base = ("kin_time_s",) if getattr(self.config, "base", "cam") == "kinematic" else ()
        return raw_columns(self.inputs + base)

    def table_constants(self, table: ProgramTable) -> dict[str, float]:
        """Machine constants for `table`: from its profile, else the ones the model was trained with; the
        planner constants of the kinematic time from its profile (the sim mechanisms' defaults without one)."""
        machine = profile_constants(table.profile) if table.profile is not None else self.constants
        return {**machine, **planner_inputs(table.profile)}

    def base_time(self, table: ProgramTable) -> np.ndarray:
        """Per block the time a model's output is a factor on: its config's `base` ("cam" without one),
        `features.base_time`."""
        return base_time(table, getattr(self.config, "base", "cam"), self.table_constants(table), needed_by=self.name)

    @property
    def trained(self) -> bool:
        return bool(self.fingerprint)

    def check_trained(self) -> None:
        if not self.trained:
            raise ModelError(f"model {self.name!r} is not trained")


def register_model(cls: type[Model]) -> type[Model]:
    return MODELS.add(cls.name, cls)


def model_class(name: str) -> type[Model]:
    return MODELS.get(name)


def make_config(name: str, *, preset: str = "full", **overrides: Any) -> ModelConfig:
    cls = model_class(name).config_class
    if preset not in PRESETS:
        raise ModelError(f"unknown preset {preset!r}; known: {', '.join(PRESETS)}")
    values = dict(cls.presets.get(preset, {})) if preset != "full" else {}
    values.update(overrides)
    return cls.from_dict(values)


def make_model(name: str, *, preset: str = "full", **overrides: Any) -> Model:
    return model_class(name)(make_config(name, preset=preset, **overrides))


def model_names() -> list[str]:
    return MODELS.names()


def _load_builtins(_registry: Registry[type[Model]]) -> None:
    # the built-in models register themselves on import, in this order
    import feedlog.train.model_mlp
    import feedlog.train.model_seq
    import feedlog.train.model_final
    import feedlog.train.model_hybrid  # noqa: F401


MODELS: Registry[type[Model]] = Registry("model", error=ModelError, load=_load_builtins)
