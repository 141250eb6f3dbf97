"""Trains ZOCR-Net (seed 001's zero-order and colour-crosstalk removal) on
`highspeed_dataset` folders and exports it for slscan.

    python -m training.highspeed.train --data out/hs-train --kind onestep --profile cpu --out models

The loss is L1 on each LED band's AC (what the demodulator reads) plus a
quarter of L1 on its zero order (what the decoder's modulation test
compares against). Writes models/highspeed_zocr.onnx, its metadata (.json)
and a golden input/output pair (.golden.bin).
"""

import argparse

import torch
import torch.nn.functional as F

from .. import common
from . import data, model

CONFIGS = {
    "cpu": {"width": 16, "crop": 96, "batch": 16, "steps": 9000, "lr": 2e-3, "minutes": 25, "threads": 2},
    "gpu": {"width": 24, "crop": 96, "batch": 64, "steps": 20000, "lr": 1e-3, "minutes": 9, "threads": 8},
}

NAME = "highspeed_zocr"
DC_WEIGHT = 0.25


def loss_terms(pred, target):
    ac = F.l1_loss(pred[:, :3], target[:, :3])
    dc = F.l1_loss(pred[:, 3:], target[:, 3:])
    return ac + DC_WEIGHT * dc, {"ac": ac, "dc": dc}


def train(args):
    if args.kind != "onestep":
        raise SystemExit("ZOCR-Net is a one-step network (--kind onestep)")
    cfg = common.profile_config(CONFIGS, args)
    torch.manual_seed(args.seed)
    torch.set_num_threads(cfg["threads"])
    device = "cuda" if args.profile == "gpu" and torch.cuda.is_available() else "cpu"
    manifest, samples = data.load(args.data)
    crops = data.Crops(samples, cfg["crop"], args.seed)
    net = model.ZocrNet(cfg["width"]).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg["lr"], weight_decay=0.0)

    def batch_loss(_step):
        cond, target = (t.to(device) for t in crops.batch(cfg["batch"]))
        return loss_terms(net(cond), target)

    steps_done, elapsed, history = common.fit(net, opt, cfg, batch_loss)
    export(net.cpu().eval(), args, cfg, manifest, steps_done, elapsed, history)


def export(net, args, cfg, manifest, steps_done, elapsed, history):
    path, names, tensors = common.export_onnx(
        net, args.out, NAME, cfg["crop"], data.IN_CHANNELS, data.OUT_CHANNELS, (0.0, 1.0)
    )
    final = common.final_losses(history)
    meta = {
        "network": NAME,
        "kind": "onestep",
        "inputs": names,
        "tile": cfg["crop"],
        "cond_channels": data.IN_CHANNELS,
        "frame_channels": data.OUT_CHANNELS,
        # The camera's frame goes in as it is (full scale 1); s_min is the
        # smallest zero order the decoder trusts, a share of full scale.
        "normalisation": {"s_min": 0.002, "doc": data.__doc__.strip()},
        "schedule": None,
        "periods_px": manifest["periods_px"],
        "steps_per_period": 1,
        "outputs": "per LED band (R, G, B): fringe AC without crosstalk, then zero order",
        "data": common.data_meta(manifest, args.data),
        "losses": {"dc_weight": DC_WEIGHT, "final": final},
    } | common.run_meta(args, cfg, net, steps_done, elapsed, NAME, tensors)
    common.write_meta(args.out, NAME, meta, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_args(ap, "highspeed_dataset folder")
    ap.add_argument("--profile", choices=list(CONFIGS), default="cpu")
    train(ap.parse_args())


if __name__ == "__main__":
    main()
