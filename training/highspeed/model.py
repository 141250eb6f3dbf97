"""ZOCR-Net, seed 001's first stage, compact for 2 cores: a TriPath CNN (a
stem, then three parallel paths of two dilated 3x3 convolutions, dilation 1,
3 and 7, so the widest sees about 33 px, two to four fringe periods on the
camera), a squeeze-and-excitation module over the three paths' features, a
1x1 fusion and a 3x3 output. Input: the camera's R, G, B; output: each LED
band's fringe AC without crosstalk (3 channels) and its zero order (3).
Fully convolutional at full resolution, so tiles of any size work.
"""

import torch
from torch import nn
import torch.nn.functional as F

from .data import IN_CHANNELS, OUT_CHANNELS

DILATIONS = (1, 3, 7)


class SqueezeExcite(nn.Module):
    """Channel weights from the features' global means."""

    def __init__(self, c, reduction=4):
        super().__init__()
        self.down = nn.Conv2d(c, c // reduction, 1)
        self.up = nn.Conv2d(c // reduction, c, 1)

    def forward(self, x):
        s = x.mean(dim=(2, 3), keepdim=True)
        return x * torch.sigmoid(self.up(F.silu(self.down(s))))


class ZocrNet(nn.Module):
    diffusion = False

    def __init__(self, width=16):
        super().__init__()
        self.stem = nn.Conv2d(IN_CHANNELS, width, 3, padding=1)
        self.paths = nn.ModuleList(
            nn.Sequential(
                nn.Conv2d(width, width, 3, padding=d, dilation=d),
                nn.SiLU(),
                nn.Conv2d(width, width, 3, padding=d, dilation=d),
                nn.SiLU(),
            )
            for d in DILATIONS
        )
        self.se = SqueezeExcite(len(DILATIONS) * width)
        self.fuse = nn.Conv2d(len(DILATIONS) * width, width, 1)
        self.out = nn.Conv2d(width, OUT_CHANNELS, 3, padding=1)

    def forward(self, cond):
        h = F.silu(self.stem(cond))
        y = self.se(torch.cat([p(h) for p in self.paths], dim=1))
        return self.out(F.silu(self.fuse(y)) + h)
