"""What every network's training entry point shares: the command line, the
profile overrides, the learning-rate schedule, and the export (ONNX file,
golden input/output pair, metadata JSON) that slscan's `infer` module loads
and its parity test holds tract to."""

import hashlib
import json
import os
import platform
import time

import numpy as np
import torch


def manifest_hash(folder):
    """SHA-256 of a dataset folder's manifest.json, recorded in the metadata
    so a model names the exact data it learnt from."""
    with open(os.path.join(folder, "manifest.json"), "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def read_manifest(folder, kind):
    """A dataset folder's manifest.json, refused unless it is of `kind`
    (compared without case: hil-sim writes "Aliased")."""
    with open(os.path.join(folder, "manifest.json")) as f:
        m = json.load(f)
    if str(m.get("kind", "")).lower() != kind.lower():
        raise ValueError(f"{folder}: manifest kind {m.get('kind')!r}, expected {kind!r}")
    return m


def data_meta(manifest, folder):
    """The metadata's `data` block: what slscan's loader and the model card
    read (kind, seed, count, camera size, the manifest's hash)."""
    block = {
        "kind": manifest["kind"], "seed": manifest["seed"], "count": manifest["count"],
        "size": [manifest["width"], manifest["height"]],
    }
    if "dmd" in manifest:
        block["dmd"] = manifest["dmd"]
    block["manifest_sha256"] = manifest_hash(folder)
    return block


def run_meta(args, cfg, net, steps_done, elapsed, name, tensors):
    """The metadata fields every run records: profile, configuration,
    parameters, steps, time, hardware, seed and the golden pair."""
    return {
        "profile": args.profile,
        "config": cfg,
        "parameters": sum(p.numel() for p in net.parameters()),
        "train_steps": steps_done,
        "train_seconds": round(elapsed, 1),
        "hardware": hardware(args.profile),
        "seed": args.seed,
        "golden": golden_meta(name, tensors),
    }


def add_args(ap, data_help):
    """The options of every `train.py`; `data_help` names its dataset kind."""
    ap.add_argument("--data", required=True, help=data_help)
    ap.add_argument("--kind", choices=["onestep", "diffusion"], required=True)
    ap.add_argument("--out", default="models")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, help="override the profile's step count")
    ap.add_argument("--minutes", type=float, help="override the profile's time limit")
    ap.add_argument("--threads", type=int, help="override the profile's CPU threads")
    ap.add_argument("--lr", type=float, help="override the profile's peak learning rate")


def profile_config(configs, args):
    """The profile's configuration with the command line's overrides."""
    cfg = dict(configs[args.profile])
    for k in ("steps", "minutes", "threads", "lr"):
        if getattr(args, k):
            cfg[k] = getattr(args, k)
    return cfg


def set_lr(opt, cfg, step, start):
    """Warm-up over 100 steps, then cosine decay over whichever budget
    (steps or minutes) runs out first."""
    done = max(step / cfg["steps"], (time.time() - start) / (cfg["minutes"] * 60))
    for group in opt.param_groups:
        group["lr"] = cfg["lr"] * min(1.0, step / 100) * 0.5 * (1 + np.cos(np.pi * min(done, 1.0)))


def export_onnx(net, out, name, tile, cond_channels, frame_channels, cond_range):
    """Writes `out/name.onnx` and its golden pair `out/name.golden.bin` (raw
    little-endian f32: the inputs in order, then the output) for a seeded
    random condition in `cond_range` (and, for a diffusion model, a noisy
    frame and t = 0.5). Returns the ONNX path, the input names and the
    (name, tensor) list written."""
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, f"{name}.onnx")
    g = torch.Generator().manual_seed(7)
    low, high = cond_range
    cond = torch.rand(1, cond_channels, tile, tile, generator=g)
    if (low, high) != (0.0, 1.0):
        cond = cond * (high - low) + low
    if net.diffusion:
        x_t = torch.randn(1, frame_channels, tile, tile, generator=g)
        t = torch.tensor([0.5])
        inputs, names = (cond, x_t, t), ["cond", "x_t", "t"]
    else:
        inputs, names = (cond,), ["cond"]
    torch.onnx.export(net, inputs, path, input_names=names, output_names=["x0"], opset_version=17, dynamo=False)
    with torch.no_grad():
        out_tensor = net(*inputs)
    tensors = list(zip(names, inputs)) + [("x0", out_tensor)]
    with open(os.path.join(out, f"{name}.golden.bin"), "wb") as f:
        for _, x in tensors:
            f.write(x.detach().numpy().astype("<f4").tobytes())
    return path, names, tensors


def fit(net, opt, cfg, batch_loss):
    """The training loop every network shares: `batch_loss(step)` gives a
    batch's loss and its named terms; gradients clipped at 1, the learning
    rate from `set_lr`, a line every 100 steps, stopping at the profile's
    steps or minutes. Returns (steps done, seconds, per-step loss history)."""
    start = time.time()
    history = []
    step = 0
    for step in range(1, cfg["steps"] + 1):
        loss, terms = batch_loss(step)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        set_lr(opt, cfg, step, start)
        opt.step()
        history.append({k: v.item() for k, v in terms.items()} | {"total": loss.item()})
        if step % 100 == 0:
            last = final_losses(history)
            print(f"step {step}/{cfg['steps']} " + " ".join(f"{k} {v:.5f}" for k, v in last.items()) + f" {time.time() - start:.0f}s", flush=True)
        if time.time() - start > cfg["minutes"] * 60:
            print(f"time limit at step {step}", flush=True)
            break
    return step, time.time() - start, history


def final_losses(history):
    """Each loss term's mean over the last 100 steps."""
    return {k: float(np.mean([h[k] for h in history[-100:]])) for k in history[-1]}


def hardware(profile):
    """The machine the training ran on, for the model card."""
    return f"{platform.processor() or platform.machine()}, torch {torch.__version__}, {torch.get_num_threads()} threads" + (
        f", {torch.cuda.get_device_name()}" if torch.cuda.is_available() and profile == "gpu" else ""
    )


def golden_meta(name, tensors):
    """The metadata's description of the golden pair."""
    return {"file": f"{name}.golden.bin", "tensors": [{"name": n, "shape": list(x.shape)} for n, x in tensors]}


def write_meta(out, name, meta, path):
    """Writes `out/name.json` and says what was written."""
    with open(os.path.join(out, f"{name}.json"), "w") as f:
        json.dump(meta, f, indent=1)
    print(f"wrote {path} ({os.path.getsize(path)} bytes, {meta['parameters']} parameters)")
