"""The peer of `cargo bench -p slscan --bench calibration`: the same solve in OpenCV.

`cv2.calibrateCamera` on the board points and detected corners the bench wrote (corner
detection is not part of either side's time), with k3 fixed at zero as slscan's default
and OpenCV's default termination criteria.

Usage: python3 calibrate_opencv.py DIR REPEATS
DIR holds job.json (width, height) and board.npy ((V, N, 3) float64 board points, metres,
z = 0) and image.npy ((V, N, 2) float64 pixels). Prints one JSON line: {"opencv": version,
"best_s": ..., "rms_px": ..., "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"}.
"""

import json
import os
import sys
import time

import cv2
import numpy as np


def main():
    directory, repeats = sys.argv[1], int(sys.argv[2])
    with open(os.path.join(directory, "job.json")) as f:
        job = json.load(f)
    # OpenCV takes float32 points (its assertion): 1e-4 px at 1000 px, far below the noise.
    board = [v.astype(np.float32) for v in np.load(os.path.join(directory, "board.npy"))]
    image = [v.astype(np.float32).reshape(-1, 1, 2) for v in np.load(os.path.join(directory, "image.npy"))]
    size = (job["width"], job["height"])
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        rms, k, dist, _, _ = cv2.calibrateCamera(board, image, size, None, None, flags=cv2.CALIB_FIX_K3)
        best = min(best, time.perf_counter() - t0)
    d = dist.ravel()
    print(
        json.dumps(
            {
                "opencv": cv2.__version__,
                "threads": cv2.getNumThreads(),
                "best_s": best,
                "rms_px": rms,
                "fx": k[0, 0],
                "fy": k[1, 1],
                "cx": k[0, 2],
                "cy": k[1, 2],
                "k1": d[0],
                "k2": d[1],
                "p1": d[2],
                "p2": d[3],
                "k3": d[4],
            }
        )
    )


if __name__ == "__main__":
    main()
