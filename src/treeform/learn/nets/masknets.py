"""Species CNN and cascaded RBV CNN over semantic masks (seed 003 §4.2.3–4.2.4, Table 1).

Both read the (N, 3, 96, 96) mask channels of :func:`treeform.learn.masks.mask_input`
through the same kind of small convolutional encoder (five strided 3x3 stages and a dense
layer; the paper's ablation "common CNN" has 8 conv and 3 dense layers).

- :class:`SpeciesNet` ends in 7 logits (the species of Appendix Table 2).
- :class:`RBVNet` is the paper's cascade: level 1 (1x1) is regressed from the mask
  features; each level k = 2..5 (2^(k-1) layers x sectors) is regressed from the features
  *and the previous level's prediction*, as a refinement of that prediction upsampled to
  the finer grid. The output is the five levels flattened and concatenated (1 + 4 + 16 +
  64 + 256 = 341 values), trained with a Huber loss on every level.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from treeform.learn.nets.blocks import conv_bn

__all__ = ["MaskEncoder", "SpeciesNet", "RBVNet", "RBV_SIZES", "split_levels"]

RBV_SIZES = (1, 2, 4, 8, 16)


class MaskEncoder(nn.Module):
    """(N, 3, 96, 96) -> (N, features)."""

    def __init__(self, features: int = 256, width: int = 24):
        super().__init__()
        w = width
        self.conv = nn.Sequential(conv_bn(3, w, 3, 2), conv_bn(w, w),                 # 48
                                  conv_bn(w, 2 * w, 3, 2), conv_bn(2 * w, 2 * w),      # 24
                                  conv_bn(2 * w, 3 * w, 3, 2), conv_bn(3 * w, 3 * w),  # 12
                                  conv_bn(3 * w, 4 * w, 3, 2),                         # 6
                                  conv_bn(4 * w, 4 * w, 3, 2))                         # 3
        self.fc = nn.Sequential(nn.Flatten(), nn.Linear(4 * w * 9, features), nn.ReLU(inplace=True),
                                nn.Dropout(0.2))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.conv(x))


class SpeciesNet(nn.Module):
    """Mask -> species logits."""

    def __init__(self, classes: int = 7):
        super().__init__()
        self.encoder = MaskEncoder()
        self.head = nn.Linear(256, classes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.encoder(x))


class RBVNet(nn.Module):
    """Mask -> RBV levels 1..5, each conditioned on the previous (cascade)."""

    def __init__(self):
        super().__init__()
        self.encoder = MaskEncoder()
        heads = [nn.Sequential(nn.Linear(256, 128), nn.ReLU(inplace=True), nn.Linear(128, 1))]
        for k in range(1, len(RBV_SIZES)):
            prev, cur = RBV_SIZES[k - 1] ** 2, RBV_SIZES[k] ** 2
            heads.append(nn.Sequential(nn.Linear(256 + prev, 256), nn.ReLU(inplace=True), nn.Linear(256, cur)))
        self.heads = nn.ModuleList(heads)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        f = self.encoder(x)
        n = x.shape[0]
        pred = self.heads[0](f) + 0.5
        outs = [pred]
        for k in range(1, len(RBV_SIZES)):
            s0, s1 = RBV_SIZES[k - 1], RBV_SIZES[k]
            up = F.interpolate(pred.view(n, 1, s0, s0), size=(s1, s1), mode="nearest").reshape(n, s1 * s1)
            pred = up + self.heads[k](torch.cat([f, pred], 1))
            outs.append(pred)
        return torch.cat(outs, 1)


def split_levels(flat):
    """(N, 341) -> list of five (N, s, s) arrays / tensors (levels 1..5)."""
    out, i = [], 0
    for s in RBV_SIZES:
        out.append(flat[:, i:i + s * s].reshape(-1, s, s))
        i += s * s
    return out
