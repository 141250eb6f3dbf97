"""The peer of `cargo bench -p slscan --bench icp`: the same registration in Open3D.

Normals of the target cloud from its k nearest neighbours, then point-to-plane ICP of the
source onto the target from the same initial guess, the way an Open3D user would write it,
in two set-ups, each timed:

- "defaults": a coarse pass on every 20th source point at the bench's initial gate, then
  a fine pass on every point at its final gate, Open3D's default convergence criteria and
  no robust kernel;
- "robust": the same coarse pass, then at the final gate a pass on every 4th point with
  a Tukey kernel (k = 5 x the depth noise) run until it stops moving (relative criteria
  1e-10, up to 100 iterations), then one on every point with the Tukey kernel and default
  criteria. Without the kernel Open3D's estimate stays several times further from the
  truth than slscan's; this is the fastest set-up found that matches slscan's error.

Usage: python3 icp_open3d.py DIR REPEATS
DIR holds job.json (k, initial_gate_m, final_gate_m, noise_m) and target.npy, source.npy
((N, 3) float64, metres) and initial.npy (4x4 float64, source -> target). Prints one JSON
line: {"open3d": version, "normals_s": best, "setups": {name: {"icp_s": best,
"transform": 4x4, "fitness": ..., "inlier_rmse_m": ...}}}. Timing excludes reading the
files and building the Open3D clouds from numpy (slscan's side has its points in memory
too); Open3D's ICP builds its kd-tree inside each call, so that is timed.
"""

import json
import os
import sys
import time

import numpy as np
import open3d as o3d

REG = o3d.pipelines.registration


def passes(job):
    """Each set-up as a list of (gate, every k-th point, estimation, criteria)."""
    plain = REG.TransformationEstimationPointToPlane()
    tukey = REG.TransformationEstimationPointToPlane(REG.TukeyLoss(k=5.0 * job["noise_m"]))
    default = REG.ICPConvergenceCriteria()
    still = REG.ICPConvergenceCriteria(
        relative_fitness=1e-10, relative_rmse=1e-10, max_iteration=100
    )
    coarse = (job["initial_gate_m"], 20, plain, default)
    fine = job["final_gate_m"]
    return {
        "defaults": [coarse, (fine, 1, plain, default)],
        "robust": [coarse, (fine, 4, tukey, still), (fine, 1, tukey, default)],
    }


def register(target, source, initial, setup):
    """Runs the passes of one set-up; returns the last pass's result."""
    transform = initial
    for gate, every, estimation, criteria in setup:
        used = source if every == 1 else source.uniform_down_sample(every)
        result = REG.registration_icp(used, target, gate, transform, estimation, criteria)
        transform = result.transformation
    return result


def main():
    directory, repeats = sys.argv[1], int(sys.argv[2])
    with open(os.path.join(directory, "job.json")) as f:
        job = json.load(f)
    target_points = np.load(os.path.join(directory, "target.npy"))
    source_points = np.load(os.path.join(directory, "source.npy"))
    initial = np.load(os.path.join(directory, "initial.npy"))
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(source_points))
    best_normals = float("inf")
    for _ in range(repeats):
        target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(target_points))
        t0 = time.perf_counter()
        target.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=job["k"]))
        best_normals = min(best_normals, time.perf_counter() - t0)
    setups = {}
    for name, setup in passes(job).items():
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            result = register(target, source, initial, setup)
            best = min(best, time.perf_counter() - t0)
        setups[name] = {
            "icp_s": best,
            "transform": np.asarray(result.transformation).tolist(),
            "fitness": result.fitness,
            "inlier_rmse_m": result.inlier_rmse,
        }
    print(json.dumps({"open3d": o3d.__version__, "normals_s": best_normals, "setups": setups}))


if __name__ == "__main__":
    main()
