"""The torch networks of the three papers (the training and data handling live in the model modules)."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn.utils.rnn import pack_padded_sequence


class AxisMLP(nn.Module):
    """Sun Fig. 4: tanh hidden layers (default 5 and 10 neurons), linear output (Eq. 1-4)."""

    def __init__(self, n_inputs: int, hidden: Sequence[int] = (5, 10)) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        width = n_inputs
        for h in hidden:
            layers += [nn.Linear(width, h), nn.Tanh()]
            width = h
        layers.append(nn.Linear(width, 1))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x).squeeze(-1)


class BiLSTMSeq(nn.Module):
    """Chien Fig. 7: bidirectional LSTM, one output per step (sequence to sequence)."""

    def __init__(self, n_inputs: int, hidden: int = 20, layers: int = 1) -> None:
        super().__init__()
        self.lstm = nn.LSTM(n_inputs, hidden, num_layers=layers, batch_first=True, bidirectional=True)
        self.head = nn.Linear(2 * hidden, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out, _ = self.lstm(x)
        return self.head(out).squeeze(-1)


class BiLSTMLast(nn.Module):
    """Chien Fig. 8: bidirectional LSTM read to the last step, one output per sequence.

    Variable lengths are packed, so padding never enters the recurrence: the forward direction's
    state after the last real CL line and the backward direction's state after the first one feed
    the output layer.
    """

    def __init__(self, n_inputs: int, hidden: int = 50, layers: int = 1) -> None:
        super().__init__()
        self.lstm = nn.LSTM(n_inputs, hidden, num_layers=layers, batch_first=True, bidirectional=True)
        self.head = nn.Linear(2 * hidden, 1)

    def forward(self, x: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        packed = pack_padded_sequence(x, lengths.cpu(), batch_first=True, enforce_sorted=False)
        _, (h, _) = self.lstm(packed)
        last = torch.cat([h[-2], h[-1]], dim=-1)  # last layer: forward, backward
        return self.head(last).squeeze(-1)


class BiLSTMUnit(nn.Module):
    """Lee Eq. 4-5: Dropout(LayerNorm(concat(forward LSTM, backward LSTM)))."""

    def __init__(self, n_inputs: int, hidden: int, dropout: float) -> None:
        super().__init__()
        self.lstm = nn.LSTM(n_inputs, hidden, batch_first=True, bidirectional=True)
        self.norm = nn.LayerNorm(2 * hidden)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out, _ = self.lstm(x)
        return self.drop(self.norm(out))


class BiLSTMR(nn.Module):
    """Lee Eq. 6-7: stacked BiLSTM units with skip connections, a linear layer per time step."""

    def __init__(self, n_inputs: int, hidden: int = 32, units: int = 2, dropout: float = 0.3) -> None:
        super().__init__()
        self.units = nn.ModuleList(
            BiLSTMUnit(n_inputs if i == 0 else 2 * hidden, hidden, dropout) for i in range(units))
        self.head = nn.Linear(2 * hidden, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = self.units[0](x)
        for unit in self.units[1:]:
            z = unit(z) + z
        return self.head(z).squeeze(-1)
