"""The seed-000 network: a ShuffleNetV2 backbone and a regression head to one Gamma.

Seed 000 (section "CNN"): the backbone's 1024 features are reduced to one value "by
combining a set of linear layers with LeakyReLU activation functions and Batch
Normalization (1D) layers". It gives no widths; we use 1024 -> 256 -> 32 -> 1 [G].
No ImageNet weights: torchvision's are a download, and this tool runs offline; the
backbone starts from torchvision's random initialisation.
"""

from __future__ import annotations

import torch
from torch import nn
import torchvision

WIDTHS = {"0.5": torchvision.models.shufflenet_v2_x0_5,
          "1.0": torchvision.models.shufflenet_v2_x1_0,
          "1.5": torchvision.models.shufflenet_v2_x1_5,
          "2.0": torchvision.models.shufflenet_v2_x2_0}


def regression_head(features: int = 1024) -> nn.Sequential:
    return nn.Sequential(
        nn.Linear(features, 256), nn.BatchNorm1d(256), nn.LeakyReLU(0.01),
        nn.Linear(256, 32), nn.BatchNorm1d(32), nn.LeakyReLU(0.01),
        nn.Linear(32, 1))


def make_model(width: str = "1.0") -> nn.Module:
    """ShuffleNetV2 (x`width`; every width ends in 1024 features) with the Gamma head.
    Input (batch, 3, H, W) in [0, 1]; output (batch,) Gamma estimates (not clamped)."""
    if width not in WIDTHS:
        raise ValueError(f"width {width!r}: allowed {', '.join(WIDTHS)}")
    net = WIDTHS[width](weights=None)
    net.fc = regression_head(net.fc.in_features)
    return _Squeeze(net)


class _Squeeze(nn.Module):
    def __init__(self, net: nn.Module):
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x).squeeze(1)
