"""Trains a de-aliasing network on `hil-sim dataset aliased` folders and
exports it for slscan.

    python -m training.dealias.train --data out/ds-train --kind onestep --profile cpu --out models
    python -m training.dealias.train --data out/ds-train --kind diffusion --profile cpu --out models

Writes models/dealias_<kind>.onnx, its metadata (.json: normalisation, tile,
channels, schedule, data, steps, time, losses) and a golden input/output
pair (.golden.json) that slscan's parity test holds tract to.
"""

import argparse

import torch

from .. import common
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
    cfg = common.profile_config(CONFIGS, args)
    torch.manual_seed(args.seed)
    torch.set_num_threads(cfg["threads"])
    device = "cuda" if args.profile == "gpu" and torch.cuda.is_available() else "cpu"
    manifest, cams = data.load_cameras(args.data)
    crops = data.Crops(cams, cfg["crop"], args.seed)
    diffusion = args.kind == "diffusion"
    net = model.UNet(diffusion, cfg["width"]).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg["lr"], weight_decay=1e-4)
    gen = torch.Generator().manual_seed(args.seed)

    def batch_loss(_step):
        cond, x0, w = (t.to(device) for t in crops.batch(cfg["batch"]))
        if diffusion:
            t = torch.rand(x0.shape[0], generator=gen).to(device)
            eps = torch.randn(x0.shape, generator=gen).to(device)
            pred = net(cond, sampling.noisy(x0, t.cpu(), eps.cpu()).to(device), t)
        else:
            pred = net(cond)
        return loss_fn(pred, x0, w), {}

    steps_done, elapsed, history = common.fit(net, opt, cfg, batch_loss)
    export(net.cpu().eval(), args, cfg, manifest, steps_done, elapsed, history)


def export(net, args, cfg, manifest, steps_done, elapsed, history):
    name = f"dealias_{args.kind}"
    path, names, tensors = common.export_onnx(
        net, args.out, name, TILE, model.COND_CHANNELS, model.FRAME_CHANNELS, (0.0, 1.0)
    )
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
        "data": common.data_meta(manifest, args.data) | {
            "noise_scales": [min(s["noise_scale"] for s in manifest["samples"]), max(s["noise_scale"] for s in manifest["samples"])],
        },
        "final_loss": common.final_losses(history)["total"],
    } | common.run_meta(args, cfg, net, steps_done, elapsed, name, tensors)
    common.write_meta(args.out, name, meta, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_args(ap, "hil-sim dataset aliased folder")
    ap.add_argument("--profile", choices=list(CONFIGS), default="cpu")
    train(ap.parse_args())


if __name__ == "__main__":
    main()
