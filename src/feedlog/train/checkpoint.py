"""Checkpoints: one torch file holding weights, config, input features, normalisation and data fingerprint.

Loaded with `torch.load(weights_only=True)`, so a checkpoint is plain data (tensors, numbers, strings,
lists, dicts) and never runs code. `format_version` guards the layout; newer versions are refused.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import torch

from feedlog import __version__
from feedlog.atomic import atomic_output
from feedlog.errors import ModelError
from feedlog.train.features import Normaliser
from feedlog.train.registry import Model, model_class

# 2: learners have a `base` time (version 1 models all used base "cam"); 3: the kinematic base time
# joins blocks by look-ahead and runs parabolic blends rest to rest; 4: it runs blend arcs as pieces of
# their own; 5: it passes LinuxCNC's tangent junctions without an arc and holds each planner segment at
# least 1.02 servo cycles. A model with base "kinematic" from before KINEMATIC_SINCE learned its
# factors on an earlier law and is refused.
FORMAT_VERSION = 5
KINEMATIC_SINCE = 5
SUFFIX = ".pt"


def checkpoint_dict(model: Model) -> dict[str, Any]:
    model.check_trained()
    return {
        "format": "feedlog-model",
        "format_version": FORMAT_VERSION,
        "feedlog_version": __version__,
        "model": model.name,
        "config": model.config.to_dict(),
        "inputs": list(model.inputs),
        "required_columns": model.required_columns,
        "norms": {k: v.to_dict() for k, v in model.norms.items()},
        "constants": dict(model.constants),
        "params": dict(model.params),
        "fingerprint": model.fingerprint,
        "report": _plain(model.report),
        "nets": {k: net.state_dict() for k, net in model.nets.items()},
    }


def save_checkpoint(model: Model, path: str | Path, *, overwrite: bool = False) -> Path:
    path = Path(path)
    if path.exists() and not overwrite:
        raise ModelError(f"{path} exists; refusing to overwrite it")
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temporary:
        torch.save(checkpoint_dict(model), temporary)
    return path


def load_checkpoint(path: str | Path) -> Model:
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: checkpoint not found")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many kinds, with pages of text, for a file that is not a checkpoint
        raise ModelError(f"{path}: not a feedlog model checkpoint (torch.load cannot read it: "
                         f"{type(exc).__name__})") from None
    if not isinstance(data, dict) or data.get("format") != "feedlog-model":
        raise ModelError(f"{path}: not a feedlog model checkpoint")
    version = data.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ModelError(f"{path}: checkpoint format version {version!r} is not supported "
                         f"(this feedlog reads up to {FORMAT_VERSION})")
    try:
        cls = model_class(data["model"])
        config = dict(data["config"])
        if version < 2 and "base" in {f.name for f in dataclasses.fields(cls.config_class)}:
            config.setdefault("base", "cam")  # trained before the kinematic base existed
        if version < KINEMATIC_SINCE and config.get("base") == "kinematic":
            raise ModelError(f"model {data['model']!r} was trained on the kinematic base time of checkpoint "
                             f"format {version}, which this feedlog no longer computes: retrain it")
        model = cls(cls.config_class.from_dict(config))
        model.norms = {k: Normaliser.from_dict(v) for k, v in data["norms"].items()}
        model.constants = {k: float(v) for k, v in data["constants"].items()}
        model.params = dict(data["params"])
        model.fingerprint = str(data["fingerprint"])
        model.report = dict(data.get("report", {}))
        if list(model.inputs) != list(data["inputs"]):
            raise ModelError(f"inputs {data['inputs']} do not match the config's {list(model.inputs)}")
        model.build_nets()
        if set(model.nets) != set(data["nets"]):
            raise ModelError(f"networks {sorted(data['nets'])} do not match the model's {sorted(model.nets)}")
        for name, net in model.nets.items():
            net.load_state_dict(data["nets"][name])
            net.eval()
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from None
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        raise ModelError(f"{path}: malformed checkpoint ({type(exc).__name__}: {exc})") from None
    return model


def _plain(value: Any) -> Any:
    """Reports as plain data (what weights_only loading accepts)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)
