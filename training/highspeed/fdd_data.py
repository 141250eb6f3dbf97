"""Reads `highspeed_dataset ... fdd` folders (slscan's example: crops of
decoded seed 001 exposures, FDD-Net's 72 input planes and the 24 phase
corrections to learn) through their manifest.json and serves batches.

The inputs are what slscan's `highspeed::fdd::condition` computes from a
demultiplexed exposure (cosines and sines of each pattern's baseband phase,
modulation ratios capped at 2), so no normalisation; a correction is NaN
where the pixel is not to be learnt (unlit, undecoded, below the decoder's
modulation floor).
"""

import os

import numpy as np
import torch

from .. import common

PATTERNS = 24
IN_CHANNELS = 3 * PATTERNS
OUT_CHANNELS = 2 * PATTERNS
PLANES = IN_CHANNELS + PATTERNS


def read_manifest(folder):
    return common.read_manifest(folder, "highspeed-fdd")


def load(folder):
    """(manifest, array [N, 96, C, C] float32): inputs 0-71, corrections 72-95."""
    m = read_manifest(folder)
    c = m["crop"]
    out = np.empty((len(m["samples"]), PLANES, c, c), np.float32)
    for k, name in enumerate(m["samples"]):
        a = np.load(os.path.join(folder, name))
        if a.shape != (PLANES * c, c) or not np.isfinite(a[: IN_CHANNELS * c]).all():
            raise ValueError(f"{folder}/{name}: shape {a.shape}, expected {(PLANES * c, c)}, finite inputs")
        out[k] = a.reshape(PLANES, c, c)
    return m, out


class Batches:
    """Random crops, seeded: (inputs, corrections) tensors."""

    def __init__(self, crops, seed):
        self.crops = crops
        self.rng = np.random.default_rng(seed)

    def batch(self, n):
        t = torch.from_numpy(self.crops[self.rng.integers(len(self.crops), size=n)])
        return t[:, :IN_CHANNELS], t[:, IN_CHANNELS:]
