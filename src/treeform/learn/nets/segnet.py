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
- a light **decoder** (the V3+ refinement) that fuses the stride-4 features, then (beyond
  V3+, as a U-Net does) the stride-2 stem features, and a sub-pixel head (pixel shuffle:
  each stride-2 cell predicts its 2x2 pixels) so the logits come out at the input's own
  resolution. Bilinear upsampling of stride-4 logits cannot draw a twig: even the *true*
  labels, reduced to stride 4 and upsampled back, score only 33 % wood IoU (73 % mean) on
  our test scenes; at stride 2, 59 % (84 %) (``benchmarks/bench_segment.py --test-data``).
  ``fine_stride`` picks where the decoder stops (4 = plain V3+).
- optionally (``refine`` > 0) a **full-resolution refinement**: a shallow branch of the
  input's own pixels (a 3x3 convolution and a separable one, ``refine`` channels) and two
  separable 3x3 convolutions over those features and the sub-pixel logits that add a
  correction to the logits. Every other layer sees the image at stride 2 or coarser, where a
  twig one pixel wide is a faint mix with the leaves around it; here it is a line. The
  correction's last layer starts at zero, so a network grown from weights without the
  branch (``load_onnx_into(..., new_layers=("full", "refine"))``) starts as it was.

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
    fine_stride : {1, 2, 4}
        Resolution of the logits before the final upsampling (1 = the input's, by a
        sub-pixel head on the stride-2 decoder: 1.2x the stride-4 net's training step on the
        2-core CPU, where a full-resolution convolution branch took 1.6x).
    refine : int
        Channels of the full-resolution refinement (0 = none; needs ``fine_stride`` 1).

    Examples
    --------
    >>> net = SegNet(8, refine=8).eval()
    >>> tuple(net(torch.zeros(1, 3, 64, 48)).shape)
    (1, 3, 64, 48)
    """

    def __init__(self, width: int = 16, classes: int = 3, fine_stride: int = 1, refine: int = 0):
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
        if fine_stride not in (1, 2, 4):
            raise ValueError(f"fine_stride must be 1, 2 or 4, got {fine_stride}")
        self.fine_stride = fine_stride
        c = 3 * w if fine_stride == 4 else 2 * w
        self.decoder = nn.Sequential(separable(5 * w, 3 * w), separable(3 * w, c))
        if fine_stride <= 2:  # stride 2: the stem's features
            self.skip2 = conv_bn(w, w // 2, 1)
            self.decoder2 = separable(c + w // 2, w)
            c = w
        # stride 1: each stride-2 cell predicts the logits of its 2x2 pixels (pixel shuffle)
        self.head = nn.Conv2d(c, classes * (4 if fine_stride == 1 else 1), 1)
        if refine < 0 or (refine and fine_stride != 1):
            raise ValueError(f"refine must be 0, or > 0 with fine_stride 1; got {refine} with fine_stride {fine_stride}")
        self.refine_channels = int(refine)
        if refine:
            r = int(refine)
            self.full = nn.Sequential(conv_bn(3, r, 3), separable(r, r))
            self.refine = nn.Sequential(separable(r + classes, r + 4), separable(r + 4, r + 4),
                                        nn.Conv2d(r + 4, classes, 1))
            nn.init.zeros_(self.refine[-1].weight)
            nn.init.zeros_(self.refine[-1].bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, w = x.shape[2], x.shape[3]
        x = (x - self.mean) / self.std
        half = self.stem(x)
        low = self.stage4(half)
        y = self.aspp(self.atrous(self.stage8(low)))
        y = F.interpolate(y, size=low.shape[2:], mode="bilinear", align_corners=False)
        y = self.decoder(torch.cat([y, self.low(low)], 1))
        if self.fine_stride <= 2:
            y = F.interpolate(y, size=half.shape[2:], mode="bilinear", align_corners=False)
            y = self.decoder2(torch.cat([y, self.skip2(half)], 1))
        y = self.head(y)
        if self.fine_stride == 1:
            y = F.pixel_shuffle(y, 2)
            if self.refine_channels:
                y = y + self.refine(torch.cat([y, self.full(x)], 1))
            return y
        return F.interpolate(y, size=(h, w), mode="bilinear", align_corners=False)
