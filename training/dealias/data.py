"""Reads `hil-sim dataset aliased` folders through their manifest.json and
serves normalised crops around the aliased overlap.

Normalisation (slscan's `dealias::learned` does the same, bit for bit in
meaning): per pixel, with dark, own and other the three flat fields,
  s      = max(own - dark, 0) + max(other - dark, 0), at least S_MIN
  cond   = [(frame_k - dark) / s for the 16 frames, (own - dark) / s, (other - dark) / s]
  x0     = 2 (clean_k - dark) / s - (own - dark) / s        (16 channels)
so x0 is the own fringe around zero, in units of the pixel's total light,
and clean_k = dark + s (x0 + (own - dark) / s) / 2.
"""

import os

import numpy as np
import torch

from .. import common

S_MIN = 0.02


def read_manifest(folder):
    return common.read_manifest(folder, "aliased")


def normalise(aliased, flats):
    """aliased (16, H, W), flats (3, H, W) -> cond (18, H, W), scale s (H, W)."""
    dark, own, other = flats
    s = np.maximum(own - dark, 0) + np.maximum(other - dark, 0)
    s = np.maximum(s, S_MIN)
    cond = np.concatenate([(aliased - dark) / s, ((own - dark) / s)[None], ((other - dark) / s)[None]])
    return cond.astype(np.float32), s


def target(clean, flats, s):
    dark, own, _ = flats
    return (2 * (clean - dark) / s - (own - dark) / s).astype(np.float32)


class Camera:
    """One sample-camera's arrays, memory-mapped."""

    def __init__(self, folder, entry):
        load = lambda k: np.load(os.path.join(folder, entry[k]), mmap_mode="r")
        self.aliased = load("input")
        self.clean = load("target")
        self.flats = load("flats")
        self.own_u = load("own_u_px")
        _, h, w = self.flats.shape
        dark, own, other = (np.asarray(f) for f in self.flats)
        # Where the network is needed: lit by both (as the scan's flat-field test sees it).
        lit_own = own - dark > 0.01
        lit_other = other - dark > 0.01
        both = lit_own & lit_other
        ys, xs = np.nonzero(both)
        self.centres = np.stack([ys, xs], 1)
        self.shape = (h, w)

    def crop(self, y0, x0, size):
        sl = (slice(None), slice(y0, y0 + size), slice(x0, x0 + size))
        aliased = np.asarray(self.aliased[sl], dtype=np.float32)
        flats = np.asarray(self.flats[sl], dtype=np.float32)
        clean = np.asarray(self.clean[sl], dtype=np.float32)
        cond, s = normalise(aliased, flats)
        x0 = target(clean, flats, s)
        dark, own, other = flats
        weight = ((own - dark > 0.01) & (other - dark > 0.01)).astype(np.float32) * 4.0 + ((own - dark) > 0.01)
        return cond, x0, weight.astype(np.float32)


def load_cameras(folder):
    m = read_manifest(folder)
    cams = []
    for sample in m["samples"]:
        for entry in sample["cameras"]:
            cam = Camera(folder, entry)
            if len(cam.centres):
                cams.append(cam)
    if not cams:
        raise ValueError(f"{folder}: no sample has an aliased overlap")
    return m, cams


class Crops:
    """Random crops of `size` centred (up to size/2 off) on overlap pixels."""

    def __init__(self, cams, size, seed):
        self.cams = cams
        self.size = size
        self.rng = np.random.default_rng(seed)

    def batch(self, n):
        conds, xs, ws = [], [], []
        for _ in range(n):
            cam = self.cams[self.rng.integers(len(self.cams))]
            cy, cx = cam.centres[self.rng.integers(len(cam.centres))]
            h, w = cam.shape
            jitter = self.rng.integers(-self.size // 4, self.size // 4 + 1, size=2)
            y0 = int(np.clip(cy - self.size // 2 + jitter[0], 0, h - self.size))
            x0 = int(np.clip(cx - self.size // 2 + jitter[1], 0, w - self.size))
            c, x, wt = cam.crop(y0, x0, self.size)
            # Flips keep each pixel's frames as they are: the mapping is local.
            if self.rng.random() < 0.5:
                c, x, wt = c[:, ::-1], x[:, ::-1], wt[::-1]
            if self.rng.random() < 0.5:
                c, x, wt = c[:, :, ::-1], x[:, :, ::-1], wt[:, ::-1]
            c, x, wt = (np.ascontiguousarray(a) for a in (c, x, wt))
            conds.append(c)
            xs.append(x)
            ws.append(wt)
        return torch.from_numpy(np.stack(conds)), torch.from_numpy(np.stack(xs)), torch.from_numpy(np.stack(ws))
