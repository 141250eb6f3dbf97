"""Reads `highspeed_dataset` folders (slscan's example: seed 001 colour long
exposures with each LED band's AC and zero order) through their
manifest.json and serves random crops.

No normalisation: the input is the camera's R, G, B at full scale 1 (the
scan's exposure rule keeps it there), the targets are in the same units, so
slscan feeds the network the frame as the camera gives it.
"""

import os

import numpy as np
import torch

from .. import common

IN_CHANNELS = 3
OUT_CHANNELS = 6


def read_manifest(folder):
    return common.read_manifest(folder, "highspeed-zocr")


def load(folder):
    """(manifest, array [N, 9, H, W] float32): input planes 0-2, targets 3-8."""
    m = read_manifest(folder)
    w, h = m["width"], m["height"]
    out = np.empty((len(m["samples"]), 9, h, w), np.float32)
    for k, name in enumerate(m["samples"]):
        a = np.load(os.path.join(folder, name))
        if a.shape != (9 * h, w) or not np.isfinite(a).all():
            raise ValueError(f"{folder}/{name}: shape {a.shape}, expected {(9 * h, w)}, all finite")
        out[k] = a.reshape(9, h, w)
    return m, out


class Crops:
    """Random crops (with random 180-degree turns: a fringe's phase
    reverses, its zero order does not) from the samples, seeded."""

    def __init__(self, samples, crop, seed):
        self.samples = samples
        self.crop = crop
        self.rng = np.random.default_rng(seed)

    def batch(self, n):
        _, _, h, w = self.samples.shape
        c = self.crop
        out = np.empty((n, 9, c, c), np.float32)
        for b in range(n):
            k = self.rng.integers(len(self.samples))
            y, x = self.rng.integers(h - c + 1), self.rng.integers(w - c + 1)
            patch = self.samples[k, :, y : y + c, x : x + c]
            if self.rng.random() < 0.5:
                patch = patch[:, ::-1, ::-1]
            out[b] = patch
        t = torch.from_numpy(out)
        return t[:, :IN_CHANNELS], t[:, IN_CHANNELS:]
