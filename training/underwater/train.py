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

import torch

from .. import common
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
    cfg = common.profile_config(CONFIGS, args)
    torch.manual_seed(args.seed)
    torch.set_num_threads(cfg["threads"])
    device = "cuda" if args.profile == "gpu" and torch.cuda.is_available() else "cpu"
    manifest, samples = data.load(args.data)
    crops = data.Crops(samples, cfg["crop"], args.seed)
    diffusion = args.kind == "diffusion"
    net = model.UNet(diffusion, cfg["width"], COND_CHANNELS, FRAME_CHANNELS).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg["lr"], weight_decay=0.0)
    gen = torch.Generator().manual_seed(args.seed)

    def batch_loss(_step):
        cond, x0, sigma = (t.to(device) for t in crops.batch(cfg["batch"]))
        if diffusion:
            t = torch.rand(x0.shape[0], generator=gen).to(device)
            eps = torch.randn(x0.shape, generator=gen).to(device)
            pred = net(cond, sampling.noisy(x0, t.cpu(), eps.cpu()).to(device), t)
        else:
            pred = net(cond)
        return losses.total(pred, x0, sigma, net)

    steps_done, elapsed, history = common.fit(net, opt, cfg, batch_loss)
    export(net.cpu().eval(), args, cfg, manifest, steps_done, elapsed, history)


def export(net, args, cfg, manifest, steps_done, elapsed, history):
    name = f"underwater_{args.kind}"
    path, names, tensors = common.export_onnx(
        net, args.out, name, TILE, COND_CHANNELS, FRAME_CHANNELS, (-1.0, 1.0)
    )
    final = common.final_losses(history)
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
        "data": common.data_meta(manifest, args.data),
        "losses": {"weights": losses.WEIGHTS, "final": final},
    } | common.run_meta(args, cfg, net, steps_done, elapsed, name, tensors)
    common.write_meta(args.out, name, meta, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_args(ap, "underwater_dataset folder")
    ap.add_argument("--profile", choices=list(CONFIGS), default="cpu")
    train(ap.parse_args())


if __name__ == "__main__":
    main()
