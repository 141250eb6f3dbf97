"""FDD-Net, seed 001's third stage, compact for 2 cores and residual: a
trunk of dilated 3x3 convolutions (dilation 1, 2, 4, 8, 16, so it sees
about 63 px, as far as the analytic windows reach) over every pattern's
demodulated baseband, then eight direction experts (a grouped 1x1
convolution, one group per fringe direction) giving each of their three
patterns a numerator and a denominator. The experts start at zero with
denominator bias 1, so the untrained network leaves the analytic phase as
it is: it learns the correction, not the phase.
"""

import torch
from torch import nn
import torch.nn.functional as F

from .fdd_data import IN_CHANNELS, OUT_CHANNELS

DILATIONS = (1, 2, 4, 8, 16)
DIRECTIONS = 8


class FddNet(nn.Module):
    diffusion = False

    def __init__(self, width=24, expert=16):
        super().__init__()
        self.stem = nn.Conv2d(IN_CHANNELS, width, 1)
        self.trunk = nn.ModuleList(nn.Conv2d(width, width, 3, padding=d, dilation=d) for d in DILATIONS)
        self.gate = nn.Conv2d(width, DIRECTIONS * expert, 1)
        self.experts = nn.Conv2d(DIRECTIONS * expert, OUT_CHANNELS, 1, groups=DIRECTIONS)
        nn.init.zeros_(self.experts.weight)
        with torch.no_grad():
            self.experts.bias.copy_(torch.tensor([0.0, 1.0] * (OUT_CHANNELS // 2)))

    def forward(self, cond):
        h = F.silu(self.stem(cond))
        for conv in self.trunk:
            h = h + F.silu(conv(h))
        return self.experts(F.silu(self.gate(h)))
