"""The de-aliasing networks of seed 000: one small U-Net with self-attention
at the bottleneck, either conditional diffusion (input: condition + noisy
x_t, plus a timestep embedding; output: the clean x0) or one-step (input:
the condition; output: x0), same widths, so the one-step net is the
diffusion model's ablation.

Channels (see data.py): condition = 16 normalised aliased frames + own and
other flat field = 18; x0 = 16 frames of the own projector's fringe. Other
networks (training/underwater/) give their own channel counts.
"""

import math

import torch
from torch import nn
import torch.nn.functional as F

COND_CHANNELS = 18
FRAME_CHANNELS = 16


def timestep_embedding(t, dim):
    """Sinusoidal embedding of t in [0, 1] (shape [B]) -> [B, dim]."""
    half = dim // 2
    freqs = torch.exp(
        -math.log(1000.0) * torch.arange(half, dtype=torch.float32, device=t.device) / half
    )
    args = t[:, None] * 1000.0 * freqs[None, :]
    return torch.cat([torch.sin(args), torch.cos(args)], dim=1)


class Block(nn.Module):
    """Two 3x3 convolutions with group norm and SiLU; the timestep shifts the features."""

    def __init__(self, cin, cout, temb):
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, padding=1)
        self.norm1 = nn.GroupNorm(4, cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, padding=1)
        self.norm2 = nn.GroupNorm(4, cout)
        self.temb = nn.Linear(temb, cout) if temb else None
        self.skip = nn.Conv2d(cin, cout, 1) if cin != cout else nn.Identity()

    def forward(self, x, emb):
        h = F.silu(self.norm1(self.conv1(x)))
        if self.temb is not None:
            h = h + self.temb(emb)[:, :, None, None]
        h = F.silu(self.norm2(self.conv2(h)))
        return h + self.skip(x)


class Attention(nn.Module):
    """Multi-head self-attention over the pixels of the bottleneck."""

    def __init__(self, c, heads=4):
        super().__init__()
        self.heads = heads
        self.norm = nn.GroupNorm(4, c)
        self.qkv = nn.Conv2d(c, 3 * c, 1)
        self.out = nn.Conv2d(c, c, 1)

    def forward(self, x):
        b, c, h, w = x.shape
        q, k, v = self.qkv(self.norm(x)).reshape(b, 3, self.heads, c // self.heads, h * w).unbind(1)
        att = torch.softmax(torch.einsum("bhci,bhcj->bhij", q, k) / math.sqrt(c // self.heads), dim=-1)
        y = torch.einsum("bhij,bhcj->bhci", att, v).reshape(b, c, h, w)
        return x + self.out(y)


class UNet(nn.Module):
    """Three levels (width, 2 width, 4 width), attention at the lowest."""

    def __init__(self, diffusion, width=16, cond_channels=COND_CHANNELS, frame_channels=FRAME_CHANNELS):
        super().__init__()
        self.diffusion = diffusion
        self.cond_channels = cond_channels
        self.frame_channels = frame_channels
        temb = 4 * width if diffusion else 0
        cin = cond_channels + (frame_channels if diffusion else 0)
        w1, w2, w3 = width, 2 * width, 4 * width
        if diffusion:
            self.temb = nn.Sequential(nn.Linear(width, temb), nn.SiLU(), nn.Linear(temb, temb))
        self.width = width
        self.enc1 = Block(cin, w1, temb)
        self.down1 = nn.Conv2d(w1, w1, 3, stride=2, padding=1)
        self.enc2 = Block(w1, w2, temb)
        self.down2 = nn.Conv2d(w2, w2, 3, stride=2, padding=1)
        self.mid = Block(w2, w3, temb)
        self.attn = Attention(w3)
        self.up2 = nn.Conv2d(w3, w2, 3, padding=1)
        self.dec2 = Block(2 * w2, w2, temb)
        self.up1 = nn.Conv2d(w2, w1, 3, padding=1)
        self.dec1 = Block(2 * w1, w1, temb)
        self.out = nn.Conv2d(w1, frame_channels, 1)

    def forward(self, cond, x_t=None, t=None):
        if self.diffusion:
            emb = self.temb(timestep_embedding(t, self.width))
            x = torch.cat([cond, x_t], dim=1)
        else:
            emb = None
            x = cond
        e1 = self.enc1(x, emb)
        e2 = self.enc2(self.down1(e1), emb)
        m = self.attn(self.mid(self.down2(e2), emb))
        d2 = self.dec2(torch.cat([self.up2(F.interpolate(m, scale_factor=2.0, mode="nearest")), e2], 1), emb)
        d1 = self.dec1(torch.cat([self.up1(F.interpolate(d2, scale_factor=2.0, mode="nearest")), e1], 1), emb)
        return self.out(d1)
