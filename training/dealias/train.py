"""Trains a de-aliasing network on `hil-sim dataset aliased` folders and
exports it for slscan.

    python -m training.dealias.train --data out/ds-train --kind onestep --profile cpu --out models
    python -m training.dealias.train --data out/ds-train --kind diffusion --profile cpu --out models

Writes models/dealias_<kind>.onnx, its metadata (.json: normalisation, tile,
channels, schedule, data, steps, time, losses) and a golden input/output
pair (.golden.json) that slscan's parity test holds tract to.
"""

import argparse
import json
import os
import platform
import time

import numpy as np
import torch

from . import data, model, sampling

# Plain dictionaries, one per profile (nanoGPT's config/ habit).
CONFIGS = {
    # Two networks side by side on the 2-core machine, one core each: about 20 min.
    "cpu": {"width": 16, "crop": 64, "batch": 8, "steps": 6000, "lr": 2e-3, "minutes": 35, "threads": 1},
    "gpu": {"width": 32, "crop": 128, "batch": 32, "steps": 20000, "lr": 1e-3, "minutes": 9, "threads": 8},
}

TILE = 64


def loss_fn(pred, x0, weight):
    return (weight[:, None] * (pred - x0).abs()).sum() / (weight.sum() * x0.shape[1] + 1e-6)


def train(args):
    cfg = dict(CONFIGS[args.profile])
    if args.steps:
        cfg["steps"] = args.steps
    if args.minutes:
        cfg["minutes"] = args.minutes
    if args.threads:
        cfg["threads"] = args.threads
    torch.manual_seed(args.seed)
    torch.set_num_threads(cfg["threads"])
    device = "cuda" if args.profile == "gpu" and torch.cuda.is_available() else "cpu"
    manifest, cams = data.load_cameras(args.data)
    crops = data.Crops(cams, cfg["crop"], args.seed)
    diffusion = args.kind == "diffusion"
    net = model.UNet(diffusion, cfg["width"]).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg["lr"], weight_decay=1e-4)
    gen = torch.Generator().manual_seed(args.seed)
    start = time.time()
    losses = []
    step = 0
    for step in range(1, cfg["steps"] + 1):
        cond, x0, w = (t.to(device) for t in crops.batch(cfg["batch"]))
        if diffusion:
            t = torch.rand(x0.shape[0], generator=gen).to(device)
            eps = torch.randn(x0.shape, generator=gen).to(device)
            pred = net(cond, sampling.noisy(x0, t.cpu(), eps.cpu()).to(device), t)
        else:
            pred = net(cond)
        loss = loss_fn(pred, x0, w)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        # Cosine decay over whichever budget (steps or minutes) runs out first.
        done = max(step / cfg["steps"], (time.time() - start) / (cfg["minutes"] * 60))
        for group in opt.param_groups:
            group["lr"] = cfg["lr"] * min(1.0, step / 100) * 0.5 * (1 + np.cos(np.pi * min(done, 1.0)))
        opt.step()
        losses.append(loss.item())
        if step % 100 == 0:
            print(f"step {step}/{cfg['steps']} loss {np.mean(losses[-100:]):.5f} {time.time() - start:.0f}s", flush=True)
        if time.time() - start > cfg["minutes"] * 60:
            print(f"time limit at step {step}", flush=True)
            break
    elapsed = time.time() - start
    net = net.cpu().eval()
    export(net, args, cfg, manifest, step, elapsed, losses)


def export(net, args, cfg, manifest, steps_done, elapsed, losses):
    os.makedirs(args.out, exist_ok=True)
    name = f"dealias_{args.kind}"
    path = os.path.join(args.out, f"{name}.onnx")
    g = torch.Generator().manual_seed(7)
    cond = torch.rand(1, model.COND_CHANNELS, TILE, TILE, generator=g)
    if net.diffusion:
        x_t = torch.randn(1, model.FRAME_CHANNELS, TILE, TILE, generator=g)
        t = torch.tensor([0.5])
        inputs, names = (cond, x_t, t), ["cond", "x_t", "t"]
    else:
        inputs, names = (cond,), ["cond"]
    torch.onnx.export(net, inputs, path, input_names=names, output_names=["x0"], opset_version=17, dynamo=False)
    with torch.no_grad():
        out = net(*inputs)
    # Golden pair: raw little-endian f32, inputs in order then the output.
    tensors = list(zip(names, inputs)) + [("x0", out)]
    with open(os.path.join(args.out, f"{name}.golden.bin"), "wb") as f:
        for _, x in tensors:
            f.write(x.detach().numpy().astype("<f4").tobytes())
    meta = {
        "network": name,
        "kind": args.kind,
        "inputs": names,
        "tile": TILE,
        "cond_channels": model.COND_CHANNELS,
        "frame_channels": model.FRAME_CHANNELS,
        "normalisation": {"s_min": data.S_MIN, "doc": data.__doc__.strip()},
        "schedule": sampling.SCHEDULE if net.diffusion else None,
        "periods_px": manifest["samples"][0]["periods_px"],
        "steps_per_period": manifest["samples"][0]["steps"],
        "data": {
            "kind": manifest["kind"], "seed": manifest["seed"], "count": manifest["count"],
            "size": [manifest["width"], manifest["height"]],
            "manifest_sha256": data.manifest_hash(args.data),
            "noise_scales": [min(s["noise_scale"] for s in manifest["samples"]), max(s["noise_scale"] for s in manifest["samples"])],
        },
        "profile": args.profile,
        "config": cfg,
        "parameters": model.parameter_count(net),
        "train_steps": steps_done,
        "train_seconds": round(elapsed, 1),
        "hardware": f"{platform.processor() or platform.machine()}, torch {torch.__version__}, {torch.get_num_threads()} threads"
        + (f", {torch.cuda.get_device_name()}" if torch.cuda.is_available() and args.profile == "gpu" else ""),
        "final_loss": float(np.mean(losses[-100:])),
        "seed": args.seed,
        "golden": {"file": f"{name}.golden.bin", "tensors": [{"name": n, "shape": list(x.shape)} for n, x in tensors]},
    }
    with open(os.path.join(args.out, f"{name}.json"), "w") as f:
        json.dump(meta, f, indent=1)
    print(f"wrote {path} ({os.path.getsize(path)} bytes, {meta['parameters']} parameters)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="hil-sim dataset aliased folder")
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
