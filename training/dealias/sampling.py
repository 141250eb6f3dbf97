"""Noise schedule as data and few-step samplers over a denoiser callable
(k-diffusion style: adding a sampler touches no network).

The denoiser predicts x0 from (x_t, t); t in [0, 1] with the cosine
schedule alpha_bar(t) = cos^2(pi/2 (t + s)/(1 + s)) / cos^2(pi/2 s/(1 + s)).
slscan's `dealias::learned` runs the same schedule and sampler in Rust.
"""

import math

import torch

SCHEDULE = {"kind": "cosine", "s": 0.008}


def alpha_bar(t, s=SCHEDULE["s"]):
    f = lambda x: torch.cos((x + s) / (1 + s) * math.pi / 2) ** 2
    zero = torch.zeros_like(t) if torch.is_tensor(t) else torch.tensor(0.0)
    t = t if torch.is_tensor(t) else torch.tensor(float(t))
    return (f(t) / f(zero)).clamp(0.0, 1.0)


def timesteps(steps):
    """Evenly spaced t from 1 down to 0: steps + 1 values."""
    return [1.0 - i / steps for i in range(steps + 1)]


def noisy(x0, t, eps):
    ab = alpha_bar(t)[:, None, None, None]
    return ab.sqrt() * x0 + (1 - ab).sqrt() * eps


@torch.no_grad()
def sample_ddim(denoise, shape, steps, generator=None):
    """Deterministic DDIM (eta = 0) with an x0-predicting `denoise(x, t)`:
    `steps` network evaluations from pure noise."""
    x = torch.randn(shape, generator=generator)
    ts = timesteps(steps)
    x0 = None
    for t_now, t_next in zip(ts[:-1], ts[1:]):
        t = torch.full((shape[0],), t_now)
        x0 = denoise(x, t)
        ab_now, ab_next = alpha_bar(t_now), alpha_bar(t_next)
        eps = (x - ab_now.sqrt() * x0) / (1 - ab_now).sqrt().clamp_min(1e-6)
        x = ab_next.sqrt() * x0 + (1 - ab_next).sqrt() * eps
    return x0
