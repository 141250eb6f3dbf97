"""The peer of `cargo bench -p slscan --bench peers`: the same job in plain numpy.

N-step wrapped phase, modulation and background per period (atan2 over the steps),
then multi-frequency heterodyne unwrapping (beat chain, fringe orders rounded level by
level, pixels whose rounding residual is too large refused), written the way a
competent numpy user would: whole-array float32 operations, no Python loop over pixels.

Usage: python3 phase_unwrap.py DIR REPEATS
DIR holds job.json (periods_px, steps, range_px, max_residual_rad, frames: file names in
period-major order) and the frames as (height, width) float32 .npy. Writes DIR/peer_absolute.npy
(absolute phase of the finest period, NaN where refused) and prints one JSON line:
{"numpy": version, "best_s": ..., "times_s": [...], "stages_s": {...}}. Timing excludes
reading the files (slscan's side has its frames in memory too).
"""

import json
import os
import sys
import time

import numpy as np

TAU = np.float32(2.0 * np.pi)
PI = np.float32(np.pi)


def wrapped_phase(frames, steps):
    """(phase, modulation, background) of one period's N frames, float32."""
    if steps == 4:
        # The textbook 4-step form: delta_n = 0, pi/2, pi, 3pi/2.
        i0, i1, i2, i3 = frames
        re = i0 - i2
        im = i3 - i1
        total = i0 + i1
        total += i2
        total += i3
    else:
        delta = 2.0 * np.pi * np.arange(steps) / steps
        re = np.zeros_like(frames[0])
        im = np.zeros_like(frames[0])
        total = np.zeros_like(frames[0])
        for f, d in zip(frames, delta):
            re += f * np.float32(np.cos(d))
            im -= f * np.float32(np.sin(d))
            total += f
    phase = np.arctan2(im, re)
    modulation = np.hypot(re, im)
    modulation *= np.float32(2.0 / steps)
    total *= np.float32(1.0 / steps)
    return phase, modulation, total


class Heterodyne:
    """Beat chain of a period set (the same set-up as slscan's `Heterodyne::new`)."""

    def __init__(self, periods_px, range_px, max_residual_rad):
        level = [1.0 / p for p in periods_px]
        chain = [level[0]]
        while len(level) > 1:
            level = [a - b for a, b in zip(level, level[1:])]
            chain.append(level[0])
        top = chain[-1]
        unambiguous = 1.0 / abs(top)
        assert unambiguous >= range_px * (1 - 1e-9), "periods too close for the field"
        margin = max((unambiguous - range_px) / 2.0, 0.0)
        tau = 2.0 * np.pi
        self.top_floor = np.float32(tau * top * (-margin) if top > 0 else tau * top * (range_px + margin))
        self.ratios = [np.float32(a / b) for a, b in zip(chain, chain[1:])]
        self.max_residual = np.float32(max_residual_rad)

    def unwrap(self, wrapped):
        """Absolute phase of the finest period, NaN where a rounding residual is too large."""
        level = list(wrapped)
        chain = [level[0]]
        for _ in range(1, len(wrapped)):
            nxt = []
            for a, b in zip(level, level[1:]):
                d = a - b
                d[d > PI] -= TAU
                d[d <= -PI] += TAU
                nxt.append(d)
            level = nxt
            chain.append(level[0])
        top = chain[-1]
        absolute = top + TAU * np.ceil((self.top_floor - top) / TAU)
        ok = np.ones(top.shape, dtype=bool)
        for lv in range(len(wrapped) - 2, -1, -1):
            turns = (absolute * self.ratios[lv] - chain[lv]) / TAU
            order = np.rint(turns)
            ok &= np.abs(turns - order) * TAU <= self.max_residual
            absolute = chain[lv] + TAU * order
        absolute[~ok] = np.nan
        return absolute


def main():
    folder, repeats = sys.argv[1], int(sys.argv[2])
    with open(os.path.join(folder, "job.json")) as f:
        job = json.load(f)
    steps = job["steps"]
    frames = [np.load(os.path.join(folder, name)) for name in job["frames"]]
    assert all(f.dtype == np.float32 for f in frames)
    het = Heterodyne(job["periods_px"], job["range_px"], job["max_residual_rad"])
    periods = len(job["periods_px"])
    times, phase_times, unwrap_times = [], [], []
    absolute = None
    for _ in range(repeats):
        absolute = None  # free the last result first, as the Rust side does
        t0 = time.perf_counter()
        decoded = [wrapped_phase(frames[p * steps:(p + 1) * steps], steps) for p in range(periods)]
        t1 = time.perf_counter()
        absolute = het.unwrap([d[0] for d in decoded])
        t2 = time.perf_counter()
        del decoded
        times.append(t2 - t0)
        phase_times.append(t1 - t0)
        unwrap_times.append(t2 - t1)
    np.save(os.path.join(folder, "peer_absolute.npy"), absolute.astype(np.float32))
    print(json.dumps({
        "numpy": np.__version__,
        "best_s": min(times),
        "times_s": times,
        "stages_s": {"phase": min(phase_times), "unwrap": min(unwrap_times)},
    }))


if __name__ == "__main__":
    main()
