"""Reads `underwater_dataset` folders (slscan's example, 4-step sets under
water and through clear water) through their manifest.json and serves
normalised crops.

Normalisation (slscan's `underwater::learned` does the same): per pixel,
with W_k the four underwater frames and C_k the four clear-water frames,
  s      = max(mean_k W_k, S_MIN)
  cond   = [W_k / s - 1 for k] + [s / (s + LEVEL_HALF)]          (5 channels)
  x0     = C_k / mean_k C_k - 1 where mean_k C_k > C_MIN, else 0  (4 channels)
so x0 is the clean fringe's AC part over its own DC (contrast, not light
level), and a restored frame is s (1 + x0_k): the clean fringe's shape at
the underwater frame's light level.
"""

import os

import numpy as np
import torch

from .. import common

S_MIN = 0.005
LEVEL_HALF = 0.05
C_MIN = 0.02
STEPS = 4


def read_manifest(folder):
    m = common.read_manifest(folder, "underwater-sets")
    if m.get("steps") != STEPS:
        raise ValueError(f"{folder}: {m.get('steps')} steps, expected {STEPS}")
    return m


def normalise(wet):
    """wet (4, H, W) -> cond (5, H, W), s (H, W)."""
    s = np.maximum(wet.mean(0), S_MIN)
    cond = np.concatenate([wet / s - 1.0, (s / (s + LEVEL_HALF))[None]])
    return cond.astype(np.float32), s


def target(clean):
    """clean (4, H, W) -> x0 (4, H, W)."""
    m = clean.mean(0)
    x0 = np.where(m > C_MIN, clean / np.maximum(m, C_MIN) - 1.0, 0.0)
    return x0.astype(np.float32)


def load(folder):
    """(manifest, list of (cond, x0, psf_sigma_px)) for every sample."""
    m = read_manifest(folder)
    w, h = m["width"], m["height"]
    out = []
    for s in m["samples"]:
        a = np.load(os.path.join(folder, s["file"])).reshape(2 * STEPS, h, w)
        cond, _ = normalise(a[:STEPS])
        out.append((cond, target(a[STEPS:]), s["psf_sigma_px"]))
    return m, out


class Crops:
    """Random crops of random samples, seeded."""

    def __init__(self, samples, crop, seed):
        self.samples = samples
        self.crop = crop
        self.rng = np.random.default_rng(seed)

    def batch(self, n):
        conds, x0s, sigmas = [], [], []
        for _ in range(n):
            cond, x0, sigma = self.samples[self.rng.integers(len(self.samples))]
            _, h, w = cond.shape
            y = self.rng.integers(0, h - self.crop + 1)
            x = self.rng.integers(0, w - self.crop + 1)
            conds.append(cond[:, y : y + self.crop, x : x + self.crop])
            x0s.append(x0[:, y : y + self.crop, x : x + self.crop])
            sigmas.append(sigma)
        return torch.from_numpy(np.stack(conds)), torch.from_numpy(np.stack(x0s)), torch.tensor(sigmas, dtype=torch.float32)
