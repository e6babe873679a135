"""FeetNet: a compact CenterNet-style detector of trunk feet (issue 16 item 2).

A MobileNet-V2-style encoder (the blocks of :mod:`treeform.learn.nets.blocks`, as SegNet's)
down to stride 16, whose last blocks are atrous (rates 2, 4, 8) and get an image-level
pooling branch, so that a cell at a foot sees the whole tree above it and its neighbours
(a foot is where a trunk that *carries a crown* meets the ground: a post or a hanging twig
look alike at the foot); a light feature-pyramid decoder back to stride 4 (stride-8 and
stride-4 skips); a head of three channels at stride 4: the foot logit (bias started at the
prior 0.1, as CenterNet does) and the foot's sub-cell offset (x, y).

Input: (N, 3, H, W) float RGB in [0, 1], H and W multiples of 16. Output: (N, 3, H/4, W/4).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from treeform.learn.nets.blocks import InvertedResidual, conv_bn, separable

__all__ = ["FeetNet"]

MEAN = (0.45, 0.47, 0.42)
STD = (0.25, 0.24, 0.27)


class FeetNet(nn.Module):
    """Foot heatmap + offsets at stride 4 (see the module docstring).

    Parameters
    ----------
    width : int
        Channel base (16: about 0.2 M parameters).

    Examples
    --------
    >>> net = FeetNet(8).eval()
    >>> tuple(net(torch.zeros(1, 3, 64, 96)).shape)
    (1, 3, 16, 24)
    """

    def __init__(self, width: int = 16):
        super().__init__()
        w = int(width)
        c4, c8, c16 = int(1.5 * w), 2 * w, 4 * w
        self.register_buffer("mean", torch.tensor(MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(STD).view(1, 3, 1, 1))
        self.stem = nn.Sequential(conv_bn(3, w, 3, 2), InvertedResidual(w, w, expand=1))           # /2
        self.stage4 = nn.Sequential(InvertedResidual(w, c4, 2), InvertedResidual(c4, c4))           # /4
        self.stage8 = nn.Sequential(InvertedResidual(c4, c8, 2), InvertedResidual(c8, c8),         # /8
                                    InvertedResidual(c8, c8))
        self.stage16 = nn.Sequential(InvertedResidual(c8, c16, 2), InvertedResidual(c16, c16),     # /16, atrous
                                     InvertedResidual(c16, c16, dilation=2), InvertedResidual(c16, c16, dilation=4),
                                     InvertedResidual(c16, c16, dilation=8))
        self.pool = conv_bn(c16, c16, 1)
        self.lat8 = conv_bn(c8, c8, 1)
        self.fuse8 = separable(c16 + c8, c8)
        self.lat4 = conv_bn(c4, w, 1)
        self.fuse4 = nn.Sequential(separable(c8 + w, c8), separable(c8, c8))
        self.head = nn.Conv2d(c8, 3, 1)
        with torch.no_grad():
            self.head.bias.zero_()
            self.head.bias[0] = -math.log((1 - 0.1) / 0.1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = (x - self.mean) / self.std
        f4 = self.stage4(self.stem(x))
        f8 = self.stage8(f4)
        f16 = self.stage16(f8)
        f16 = f16 + self.pool(f16.mean(dim=(2, 3), keepdim=True))
        y = F.interpolate(f16, size=f8.shape[2:], mode="bilinear", align_corners=False)
        y = self.fuse8(torch.cat([y, self.lat8(f8)], 1))
        y = F.interpolate(y, size=f4.shape[2:], mode="bilinear", align_corners=False)
        y = self.fuse4(torch.cat([y, self.lat4(f4)], 1))
        return self.head(y)
