"""Compact DeepLab-V3+ for tree segmentation: background / foliage / wood (seed 003 §4.2.2).

The paper runs DeepLab-V3 (Chen et al.) with an ImageNet-pretrained Xception-41 backbone,
output stride 8 and atrous rates (6, 12, 18). Nothing pretrained can be downloaded here and
inference must fit a 2-core CPU, so the backbone is a small MobileNet-V2-style stack trained
from scratch; the DeepLab parts are kept:

- **output stride 8**: the last stages keep stride 8 and use atrous (dilated) depthwise
  convolutions (rates 2 and 4) instead of further striding;
- **ASPP**: a 1x1 branch, three atrous separable 3x3 branches (rates 3, 6, 9 at stride 8,
  i.e. the paper's 6, 12, 18 at stride 16 scaled to our input size) and image-level pooling,
  concatenated and projected;
- a light **decoder** (the V3+ refinement) that fuses the stride-4 features so thin trunks
  and crown edges survive the upsampling.

Input: (N, 3, H, W) float RGB in [0, 1] with H, W multiples of 8. Output: (N, 3, H, W)
logits for background, foliage, wood.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from treeform.learn.nets.blocks import InvertedResidual, conv_bn, separable

__all__ = ["SegNet"]

MEAN = (0.45, 0.47, 0.42)
STD = (0.25, 0.24, 0.27)


class ASPP(nn.Module):
    """Atrous spatial pyramid pooling (DeepLab-V3)."""

    def __init__(self, cin: int, cout: int, rates=(3, 6, 9)):
        super().__init__()
        self.branches = nn.ModuleList([conv_bn(cin, cout, 1)] + [separable(cin, cout, r) for r in rates])
        self.pool = conv_bn(cin, cout, 1)
        self.project = nn.Sequential(conv_bn(cout * (len(rates) + 2), cout, 1), nn.Dropout2d(0.1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        feats = [b(x) for b in self.branches]
        g = self.pool(x.mean(dim=(2, 3), keepdim=True))
        feats.append(g.expand(-1, -1, x.shape[2], x.shape[3]))
        return self.project(torch.cat(feats, 1))


class SegNet(nn.Module):
    """Compact DeepLab-V3+ (about 0.5 M parameters); see the module docstring.

    Parameters
    ----------
    width : int
        Channel multiplier base (16 -> the shipped size).
    classes : int
    """

    def __init__(self, width: int = 16, classes: int = 3):
        super().__init__()
        w = width
        self.register_buffer("mean", torch.tensor(MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(STD).view(1, 3, 1, 1))
        self.stem = nn.Sequential(conv_bn(3, w, 3, 2), InvertedResidual(w, w, expand=1))           # /2
        self.stage4 = nn.Sequential(InvertedResidual(w, int(1.5 * w), 2),                            # /4
                                    InvertedResidual(int(1.5 * w), int(1.5 * w)))
        self.stage8 = nn.Sequential(InvertedResidual(int(1.5 * w), 2 * w, 2),                        # /8
                                    InvertedResidual(2 * w, 2 * w), InvertedResidual(2 * w, 2 * w))
        self.atrous = nn.Sequential(InvertedResidual(2 * w, 4 * w, dilation=2),                      # /8, atrous
                                    InvertedResidual(4 * w, 4 * w, dilation=2),
                                    InvertedResidual(4 * w, 4 * w, dilation=4),
                                    InvertedResidual(4 * w, 6 * w, dilation=4),
                                    InvertedResidual(6 * w, 6 * w, dilation=8))
        self.aspp = ASPP(6 * w, 4 * w)
        self.low = conv_bn(int(1.5 * w), w, 1)
        self.decoder = nn.Sequential(separable(5 * w, 3 * w), separable(3 * w, 3 * w))
        self.head = nn.Conv2d(3 * w, classes, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, w = x.shape[2], x.shape[3]
        x = (x - self.mean) / self.std
        x = self.stem(x)
        low = self.stage4(x)
        y = self.aspp(self.atrous(self.stage8(low)))
        y = F.interpolate(y, size=low.shape[2:], mode="bilinear", align_corners=False)
        y = self.decoder(torch.cat([y, self.low(low)], 1))
        y = self.head(y)
        return F.interpolate(y, size=(h, w), mode="bilinear", align_corners=False)
