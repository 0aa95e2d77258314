"""The training loop every model shares: seeded, deterministic, Adam + MSE, early stopping, progress bar."""

from __future__ import annotations

import copy
import random
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

MAX_THREADS = 2      # the machine is shared: never more than two
DEFAULT_THREADS = 1  # the nets are small: one thread trains and predicts them fastest (measured: a 100k-block
                     # Bi-LSTM prediction took 0.2 s on one thread, 11 s on two, on a busy 2-core machine)

# loss_fn(net, idx, split) -> scalar loss; idx indexes the split's examples (None = all of them)
LossFn = Callable[[nn.Module, "torch.Tensor | None", str], torch.Tensor]


def setup_torch(seed: int | None = None, *, threads: int = DEFAULT_THREADS) -> None:
    """At most `threads` (<= MAX_THREADS) torch threads, and all RNGs seeded when `seed` is given."""
    threads = max(1, min(threads, MAX_THREADS))
    if torch.get_num_threads() != threads:
        torch.set_num_threads(threads)
    if seed is not None:
        random.seed(seed)
        np.random.seed(seed % 2**32)
        torch.manual_seed(seed)


def train_net(net: nn.Module, loss_fn: LossFn, *, n_train: int, n_val: int, seed: int, epochs: int,
              lr: float, batch_size: int, patience: int, desc: str, progress: bool = True) -> dict[str, Any]:
    """Fit `net` in place; keep the weights of the epoch with the lowest validation loss.

    The untrained net is the first candidate (epoch 0): training that never beats it on validation
    leaves it unchanged. Without validation examples the training loss decides. Returns a small report.
    """
    setup_torch()
    optimiser = torch.optim.Adam(net.parameters(), lr=lr)
    generator = torch.Generator().manual_seed(seed)
    best = float("inf")
    if n_val:
        net.eval()
        with torch.no_grad():
            best = float(loss_fn(net, None, "val"))
    best_state, best_epoch, stale = copy.deepcopy(net.state_dict()), -1, 0
    train_loss = float("nan")
    bar = tqdm(range(epochs), desc=desc, disable=None if progress else True, leave=False, unit="epoch")  # None: off when not a terminal
    epoch = 0
    for epoch in bar:
        net.train()
        order = torch.randperm(n_train, generator=generator)
        total = 0.0
        for start in range(0, n_train, batch_size):
            idx = order[start:start + batch_size]
            optimiser.zero_grad()
            loss = loss_fn(net, idx, "train")
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 5.0)
            optimiser.step()
            total += loss.item() * len(idx)
        train_loss = total / max(n_train, 1)
        net.eval()
        if n_val:
            with torch.no_grad():
                score = float(loss_fn(net, None, "val"))
        else:
            score = train_loss
        if score < best - 1e-12:
            best, best_state, best_epoch, stale = score, copy.deepcopy(net.state_dict()), epoch, 0
        else:
            stale += 1
        bar.set_postfix(train=f"{train_loss:.4g}", val=f"{score:.4g}")
        if stale >= patience:
            break
    bar.close()
    net.load_state_dict(best_state)
    net.eval()
    return {"epochs_run": epoch + 1, "best_epoch": best_epoch + 1, "best_val_loss": best,
            "last_train_loss": train_loss, "n_train": n_train, "n_val": n_val}


def masked_mse(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    diff = (pred - target) * mask
    return (diff * diff).sum() / mask.sum().clamp_min(1.0)
