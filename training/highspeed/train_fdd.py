"""Trains FDD-Net (seed 001's third stage: each pattern's phase corrected
from every pattern's demodulated baseband) on `highspeed_dataset ... fdd`
folders and exports it for slscan.

    python -m training.highspeed.train_fdd --data out/hs-fdd --kind onestep --profile cpu --out models

`--extra-data` adds more such folders (the moving scenes' stream) to the
batches; `--init models/highspeed_fdd.onnx` starts from a shipped model's
weights (same profile widths) instead of the untrained network, so a
second run goes on where the first stopped, on its data or new data.

The loss is, over the pixels with a correction to learn, the squared
distance between the unit vector of the network's (denominator, numerator)
and that of the true correction: 2 (1 - cos(error)), so the phase error
itself, not the numerator's and denominator's scale. Writes
models/highspeed_fdd.onnx, its metadata (.json) and a golden input/output
pair (.golden.bin).
"""

import argparse

import numpy as np
import onnx
import onnx.numpy_helper
import torch

from .. import common
from . import fdd_data, fdd_model

CONFIGS = {
    "cpu": {"width": 24, "expert": 16, "batch": 8, "steps": 6000, "lr": 2e-3, "minutes": 25, "threads": 2},
    "gpu": {"width": 32, "expert": 24, "batch": 32, "steps": 20000, "lr": 1e-3, "minutes": 9, "threads": 8},
}

NAME = "highspeed_fdd"
MIN_RATIO = 0.25


def loss_terms(pred, correction):
    """Mean of 2 (1 - cos(error)) over the pixels to learn, and the same
    for the untouched analytic phase (correction zero) as a yardstick."""
    mask = torch.isfinite(correction)
    target = torch.where(mask, correction, torch.zeros_like(correction))
    num, den = pred[:, 0::2], pred[:, 1::2]
    norm = torch.sqrt(num * num + den * den + 1e-12)
    cos_err = (den * torch.cos(target) + num * torch.sin(target)) / norm
    n = mask.sum().clamp(min=1)
    loss = (2.0 * (1.0 - cos_err))[mask].sum() / n
    analytic = (2.0 * (1.0 - torch.cos(target)))[mask].sum() / n
    return loss, {"phase": loss, "analytic": analytic}


def train(args):
    if args.kind != "onestep":
        raise SystemExit("FDD-Net is a one-step network (--kind onestep)")
    cfg = common.profile_config(CONFIGS, args)
    torch.manual_seed(args.seed)
    torch.set_num_threads(cfg["threads"])
    device = "cuda" if args.profile == "gpu" and torch.cuda.is_available() else "cpu"
    manifest, crops = fdd_data.load(args.data)
    extra = [fdd_data.load(folder) for folder in args.extra_data]
    for folder, (m, _) in zip(args.extra_data, extra):
        if m["crop"] != manifest["crop"] or m["periods_px"] != manifest["periods_px"]:
            raise SystemExit(f"{folder}: crop or pattern set differs from {args.data}'s")
    crops = np.concatenate([crops] + [c for _, c in extra])
    print(f"{len(crops)} crops ({args.data}" + "".join(f", {f}" for f in args.extra_data) + ")", flush=True)
    batches = fdd_data.Batches(crops, args.seed)
    net = fdd_model.FddNet(cfg["width"], cfg["expert"])
    if args.init:
        load_onnx_weights(net, args.init)
    net = net.to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg["lr"], weight_decay=0.0)

    def batch_loss(_step):
        cond, correction = (t.to(device) for t in batches.batch(cfg["batch"]))
        return loss_terms(net(cond), correction)

    steps_done, elapsed, history = common.fit(net, opt, cfg, batch_loss)
    export(net.cpu().eval(), args, cfg, manifest, steps_done, elapsed, history)


def load_onnx_weights(net, path):
    """Copies an exported FDD-Net's initializers into `net`: every parameter
    by name, refused if one is missing or has another shape."""
    weights = {i.name: onnx.numpy_helper.to_array(i) for i in onnx.load(path).graph.initializer}
    state = net.state_dict()
    for name, value in state.items():
        if name not in weights or tuple(weights[name].shape) != tuple(value.shape):
            raise SystemExit(f"{path}: no weight {name} of shape {tuple(value.shape)} (another profile?)")
        state[name] = torch.from_numpy(weights[name].copy())
    net.load_state_dict(state)
    print(f"started from {path}", flush=True)


def export(net, args, cfg, manifest, steps_done, elapsed, history):
    tile = manifest["crop"]
    path, names, tensors = common.export_onnx(
        net, args.out, NAME, tile, fdd_data.IN_CHANNELS, fdd_data.OUT_CHANNELS, (0.0, 1.0)
    )
    meta = {
        "network": NAME,
        "kind": "onestep",
        "inputs": names,
        "tile": tile,
        "cond_channels": fdd_data.IN_CHANNELS,
        "frame_channels": fdd_data.OUT_CHANNELS,
        # No scaling of the inputs; s_min records the modulation ratio
        # (fringe over zero order, per pattern) below which nothing was
        # learnt: the decoder's own floor.
        "normalisation": {"s_min": MIN_RATIO, "doc": fdd_data.__doc__.strip()},
        "schedule": None,
        "periods_px": manifest["periods_px"],
        "steps_per_period": 1,
        "outputs": "per pattern in projection order: numerator, denominator of the phase correction",
        "data": common.data_meta(manifest, args.data),
        "extra_data": [common.data_meta(fdd_data.read_manifest(f), f) for f in args.extra_data],
        "init": args.init,
        "losses": {"final": common.final_losses(history)},
    } | common.run_meta(args, cfg, net, steps_done, elapsed, NAME, tensors)
    common.write_meta(args.out, NAME, meta, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_args(ap, "highspeed_dataset folder (fdd)")
    ap.add_argument("--profile", choices=list(CONFIGS), default="cpu")
    ap.add_argument("--extra-data", action="append", default=[], help="another highspeed_dataset folder (fdd), e.g. moving scenes")
    ap.add_argument("--init", help="start from this exported FDD-Net's weights")
    train(ap.parse_args())


if __name__ == "__main__":
    main()
