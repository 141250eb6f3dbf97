"""Seed 002's loss terms, on x0-predicting networks: L1 on the clean fringe
(the x0 form of its noise L1), 1 - SSIM, an L1 on the weights, and a
physics term in the range of its degradation operator D(I) = I * h_g: the
prediction and the target blurred by the sample's forward-scatter Gaussian
must agree (a restoration may not disagree with the clean fringe in what
the water would have kept).
"""

import torch
import torch.nn.functional as F

WEIGHTS = {"l1": 1.0, "ssim": 0.2, "physics": 0.5, "weight_l1": 1e-6}


def gaussian_blur(x, sigma):
    """Blurs each sample of x (B, C, H, W) by its own sigma (B,), pixels."""
    radius = 8
    r = torch.arange(-radius, radius + 1, dtype=x.dtype, device=x.device)
    k = torch.exp(-0.5 * (r[None, :] / sigma.clamp_min(0.3)[:, None]) ** 2)
    k = k / k.sum(1, keepdim=True)  # (B, K)
    b, c, h, w = x.shape
    y = x.reshape(1, b * c, h, w)
    kx = k.repeat_interleave(c, 0)[:, None, None, :]
    ky = k.repeat_interleave(c, 0)[:, None, :, None]
    y = F.conv2d(F.pad(y, (radius, radius, 0, 0), mode="reflect"), kx, groups=b * c)
    y = F.conv2d(F.pad(y, (0, 0, radius, radius), mode="reflect"), ky, groups=b * c)
    return y.reshape(b, c, h, w)


def ssim(a, b, c1=0.01**2, c2=0.03**2):
    """Mean SSIM over 7x7 windows of fringes in about [-1, 1] (mapped to [0, 1])."""
    a, b = (a + 1) / 2, (b + 1) / 2
    pool = lambda x: F.avg_pool2d(x, 7, 1, 3, count_include_pad=False)
    ma, mb = pool(a), pool(b)
    va, vb, cov = pool(a * a) - ma**2, pool(b * b) - mb**2, pool(a * b) - ma * mb
    s = ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma**2 + mb**2 + c1) * (va + vb + c2))
    return s.mean()


def total(pred, x0, sigma, net):
    terms = {
        "l1": (pred - x0).abs().mean(),
        "ssim": 1 - ssim(pred, x0),
        "physics": (gaussian_blur(pred, sigma) - gaussian_blur(x0, sigma)).abs().mean(),
        "weight_l1": sum(p.abs().sum() for p in net.parameters()),
    }
    return sum(WEIGHTS[k] * v for k, v in terms.items()), terms
