"""Trains the underwater restorer (seed 002) on `underwater_dataset`
folders and exports it for slscan.

    python -m training.underwater.train --data out/uw-train --kind onestep   --profile cpu --out models
    python -m training.underwater.train --data out/uw-train --kind diffusion --profile cpu --out models

The network is dealias/model.py's U-Net with 5 condition channels (the
normalised 4-step set under water and its light level) and 4 output
channels (the clear-water fringe's AC over DC), trained with seed 002's
loss terms (losses.py). `diffusion` is a conditional DDPM in x0 form on the
cosine schedule, sampled with few-step DDIM (dealias/sampling.py); `onestep`
is its ablation of the same size. Writes models/underwater_<kind>.onnx, its
metadata (.json) and a golden input/output pair (.golden.bin).
"""

import argparse
import json
import os
import platform
import time

import numpy as np
import torch

from ..dealias import model, sampling
from . import data, losses

CONFIGS = {
    # Two networks side by side on the 2-core machine, one core each.
    "cpu": {"width": 16, "crop": 64, "batch": 8, "steps": 6000, "lr": 2e-3, "minutes": 20, "threads": 1},
    "gpu": {"width": 32, "crop": 128, "batch": 32, "steps": 20000, "lr": 1e-3, "minutes": 9, "threads": 8},
}

TILE = 64
COND_CHANNELS = 5
FRAME_CHANNELS = 4


def train(args):
    cfg = dict(CONFIGS[args.profile])
    for k in ("steps", "minutes", "threads"):
        if getattr(args, k):
            cfg[k] = getattr(args, k)
    torch.manual_seed(args.seed)
    torch.set_num_threads(cfg["threads"])
    device = "cuda" if args.profile == "gpu" and torch.cuda.is_available() else "cpu"
    manifest, samples = data.load(args.data)
    crops = data.Crops(samples, cfg["crop"], args.seed)
    diffusion = args.kind == "diffusion"
    net = model.UNet(diffusion, cfg["width"], COND_CHANNELS, FRAME_CHANNELS).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg["lr"], weight_decay=0.0)
    gen = torch.Generator().manual_seed(args.seed)
    start = time.time()
    history = []
    step = 0
    for step in range(1, cfg["steps"] + 1):
        cond, x0, sigma = (t.to(device) for t in crops.batch(cfg["batch"]))
        if diffusion:
            t = torch.rand(x0.shape[0], generator=gen).to(device)
            eps = torch.randn(x0.shape, generator=gen).to(device)
            pred = net(cond, sampling.noisy(x0, t.cpu(), eps.cpu()).to(device), t)
        else:
            pred = net(cond)
        loss, terms = losses.total(pred, x0, sigma, net)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        done = max(step / cfg["steps"], (time.time() - start) / (cfg["minutes"] * 60))
        for group in opt.param_groups:
            group["lr"] = cfg["lr"] * min(1.0, step / 100) * 0.5 * (1 + np.cos(np.pi * min(done, 1.0)))
        opt.step()
        history.append({k: v.item() for k, v in terms.items()} | {"total": loss.item()})
        if step % 100 == 0:
            last = {k: np.mean([h[k] for h in history[-100:]]) for k in history[-1]}
            print(f"step {step} " + " ".join(f"{k} {v:.4f}" for k, v in last.items()) + f" {time.time() - start:.0f}s", flush=True)
        if time.time() - start > cfg["minutes"] * 60:
            print(f"time limit at step {step}", flush=True)
            break
    elapsed = time.time() - start
    export(net.cpu().eval(), args, cfg, manifest, step, elapsed, history)


def export(net, args, cfg, manifest, steps_done, elapsed, history):
    os.makedirs(args.out, exist_ok=True)
    name = f"underwater_{args.kind}"
    path = os.path.join(args.out, f"{name}.onnx")
    g = torch.Generator().manual_seed(7)
    cond = torch.rand(1, COND_CHANNELS, TILE, TILE, generator=g) * 2 - 1
    if net.diffusion:
        x_t = torch.randn(1, FRAME_CHANNELS, TILE, TILE, generator=g)
        t = torch.tensor([0.5])
        inputs, names = (cond, x_t, t), ["cond", "x_t", "t"]
    else:
        inputs, names = (cond,), ["cond"]
    torch.onnx.export(net, inputs, path, input_names=names, output_names=["x0"], opset_version=17, dynamo=False)
    with torch.no_grad():
        out = net(*inputs)
    tensors = list(zip(names, inputs)) + [("x0", out)]
    with open(os.path.join(args.out, f"{name}.golden.bin"), "wb") as f:
        for _, x in tensors:
            f.write(x.detach().numpy().astype("<f4").tobytes())
    final = {k: float(np.mean([h[k] for h in history[-100:]])) for k in history[-1]}
    meta = {
        "network": name,
        "kind": args.kind,
        "inputs": names,
        "tile": TILE,
        "cond_channels": COND_CHANNELS,
        "frame_channels": FRAME_CHANNELS,
        "normalisation": {"s_min": data.S_MIN, "level_half": data.LEVEL_HALF, "c_min": data.C_MIN, "doc": data.__doc__.strip()},
        "schedule": sampling.SCHEDULE if net.diffusion else None,
        "periods_px": manifest["periods_px"],
        "steps_per_period": manifest["steps"],
        "data": {
            "kind": manifest["kind"], "seed": manifest["seed"], "count": manifest["count"],
            "size": [manifest["width"], manifest["height"]], "dmd": manifest["dmd"],
            "manifest_sha256": data.manifest_hash(args.data),
        },
        "losses": {"weights": losses.WEIGHTS, "final": final},
        "profile": args.profile,
        "config": cfg,
        "parameters": model.parameter_count(net),
        "train_steps": steps_done,
        "train_seconds": round(elapsed, 1),
        "hardware": f"{platform.processor() or platform.machine()}, torch {torch.__version__}, {torch.get_num_threads()} threads"
        + (f", {torch.cuda.get_device_name()}" if torch.cuda.is_available() and args.profile == "gpu" else ""),
        "seed": args.seed,
        "golden": {"file": f"{name}.golden.bin", "tensors": [{"name": n, "shape": list(x.shape)} for n, x in tensors]},
    }
    with open(os.path.join(args.out, f"{name}.json"), "w") as f:
        json.dump(meta, f, indent=1)
    print(f"wrote {path} ({os.path.getsize(path)} bytes, {meta['parameters']} parameters)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="underwater_dataset folder")
    ap.add_argument("--kind", choices=["onestep", "diffusion"], required=True)
    ap.add_argument("--profile", choices=list(CONFIGS), default="cpu")
    ap.add_argument("--out", default="models")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, help="override the profile's step count")
    ap.add_argument("--minutes", type=float, help="override the profile's time limit")
    ap.add_argument("--threads", type=int, help="override the profile's CPU threads")
    train(ap.parse_args())


if __name__ == "__main__":
    main()
