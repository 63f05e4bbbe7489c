"""Pretrain seed 000's CNN on a chromasim dataset: images of both fingertips -> Gamma.

  python3 -m chromasim.train DATASET -o RUN_DIR [--epochs 50] [--batch-size 64] ...

ShuffleNetV2 + regression head (chromasim.model), MSE loss, AdamW (seed 000 used
Ranger21, built around AdamW; Ranger21 is not packaged in Debian, so plain AdamW with a
cosine learning-rate schedule stands in), ColorJitter and GaussianBlur augmentation (seed
000's; their strengths are not given: ours are [G]). CPU by default, CUDA when present.

RUN_DIR gets config.json, history.csv (one row per epoch), checkpoint_last.pt after every
epoch and checkpoint_best.pt (lowest validation MSE), each written to a temporary name and
renamed. `--resume` continues from RUN_DIR/checkpoint_last.pt.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time

import numpy as np
import torch
from torchvision import transforms
from tqdm import tqdm

from .data import DatasetError, open_dataset
from .model import WIDTHS, make_model
from .torch_data import GammaImages


def augmentation() -> transforms.Compose:
    return transforms.Compose([
        transforms.ColorJitter(brightness=0.2, contrast=0.2, saturation=0.2, hue=0.02),
        transforms.GaussianBlur(kernel_size=5, sigma=(0.1, 1.5)),
    ])


def pick_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise SystemExit("train: --device cuda: no CUDA device is available (use cpu or auto)")
    return torch.device(name)


def save_atomic(obj, path: str) -> None:
    tmp = path + ".tmp"
    torch.save(obj, tmp)
    os.replace(tmp, path)


@torch.no_grad()
def evaluate_mse(model, loader, device) -> float:
    model.eval()
    total, n = 0.0, 0
    for x, y, _ in loader:
        pred = model(x.to(device)).clamp(0.0, 1.0)
        total += float(((pred - y.to(device)) ** 2).sum())
        n += len(y)
    return total / max(n, 1)


def default_splits(d, wanted: list[str] | None, fallback: str | None) -> list[str] | None:
    if wanted:
        return wanted
    names = list(dict.fromkeys(d.labels["split"]))
    if fallback in names:
        return [fallback]
    return None


def train(args) -> tuple[torch.nn.Module, list[dict]]:
    torch.manual_seed(args.seed)
    np.random.seed(args.seed)
    # Debian's torch (OpenMP) starts with one thread here; use every CPU we may run on.
    torch.set_num_threads(args.threads or len(os.sched_getaffinity(0)))
    device = pick_device(args.device)
    data = open_dataset(args.dataset)
    train_splits = default_splits(data, args.train_splits, "train")
    train_set = GammaImages(data, train_splits, size=args.size, target=args.target,
                            transform=None if args.no_augment else augmentation(),
                            preload=args.preload)
    val_set = None
    if args.val_dataset:
        vd = open_dataset(args.val_dataset)
        val_set = GammaImages(vd, args.val_splits, size=args.size, target=args.target,
                              preload=args.preload)
    else:
        vs = default_splits(data, args.val_splits, "test")
        if vs and vs != train_splits:
            val_set = GammaImages(data, vs, size=args.size, target=args.target,
                                  preload=args.preload)
    if len(train_set) == 0:
        raise DatasetError(f"{data.root}: no training frames in splits {train_splits}")

    gen = torch.Generator().manual_seed(args.seed)
    train_loader = torch.utils.data.DataLoader(
        train_set, batch_size=args.batch_size, shuffle=True, drop_last=len(train_set) > args.batch_size,
        num_workers=args.workers, generator=gen, persistent_workers=args.workers > 0)
    val_loader = None if val_set is None else torch.utils.data.DataLoader(
        val_set, batch_size=args.batch_size, shuffle=False, num_workers=args.workers)

    model = make_model(args.width).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=args.weight_decay)
    steps_per_epoch = len(train_loader)
    total_steps = args.max_steps or args.epochs * steps_per_epoch
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: 0.5 * (1 + math.cos(math.pi * min(s, total_steps) / total_steps)))
    os.makedirs(args.out, exist_ok=True)
    history: list[dict] = []
    start_epoch, step, best = 0, 0, math.inf
    last_path = os.path.join(args.out, "checkpoint_last.pt")
    if args.resume:
        if not os.path.exists(last_path):
            raise SystemExit(f"train: --resume: {last_path}: no such file")
        ck = torch.load(last_path, map_location=device)
        model.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        sched.load_state_dict(ck["scheduler"])
        start_epoch, step, best, history = ck["epoch"], ck["step"], ck["best_val_mse"], ck["history"]
        torch.set_rng_state(ck["rng"])
    config = {k: v for k, v in vars(args).items()}
    config.update(train_frames=len(train_set), val_frames=len(val_set) if val_set else 0,
                  train_splits=train_splits, device=str(device), torch=torch.__version__,
                  dataset_name=data.manifest.get("name"),
                  dataset_sha256=data.manifest.get("spec", {}).get("sha256"))
    with open(os.path.join(args.out, "config.json"), "w") as f:
        json.dump(config, f, indent=2)

    print(f"train: {len(train_set)} frames ({train_splits or 'all splits'}), "
          f"{len(val_set) if val_set else 0} validation frames, ShuffleNetV2 x{args.width}, "
          f"{device}, {torch.get_num_threads()} threads", file=sys.stderr)
    t_start = time.perf_counter()
    loss_fn = torch.nn.MSELoss()
    for epoch in range(start_epoch, args.epochs):
        model.train()
        t0 = time.perf_counter()
        running, seen = 0.0, 0
        bar = tqdm(train_loader, desc=f"epoch {epoch + 1}/{args.epochs}", unit="batch",
                   disable=args.quiet, file=sys.stderr, dynamic_ncols=True)
        for x, y, _ in bar:
            x, y = x.to(device), y.to(device)
            loss = loss_fn(model(x), y)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            step += 1
            running += float(loss) * len(y)
            seen += len(y)
            bar.set_postfix(loss=f"{running / seen:.4f}")
            if args.max_steps and step >= args.max_steps:
                break
        train_loss = running / max(seen, 1)
        val_mse = evaluate_mse(model, val_loader, device) if val_loader else float("nan")
        row = {"epoch": epoch + 1, "step": step, "train_loss": train_loss, "val_mse": val_mse,
               "lr": sched.get_last_lr()[0], "seconds": time.perf_counter() - t0}
        history.append(row)
        print(f"epoch {epoch + 1}: train MSE {train_loss:.5f}, validation MSE {val_mse:.5f}, "
              f"{row['seconds']:.0f} s", file=sys.stderr)
        state = {"model": model.state_dict(), "optimizer": opt.state_dict(),
                 "scheduler": sched.state_dict(), "epoch": epoch + 1, "step": step,
                 "best_val_mse": best, "history": history, "rng": torch.get_rng_state(),
                 "width": args.width, "size": args.size, "target": args.target}
        if val_loader and val_mse < best:
            best = val_mse
            state["best_val_mse"] = best
            save_atomic(state, os.path.join(args.out, "checkpoint_best.pt"))
        save_atomic(state, last_path)
        _write_history(history, os.path.join(args.out, "history.csv"))
        stop = (args.max_steps and step >= args.max_steps) or \
            (args.time_limit_min and time.perf_counter() - t_start > 60 * args.time_limit_min)
        if stop:
            break
    return model, history


def _write_history(history: list[dict], path: str) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(history[0]))
        w.writeheader()
        w.writerows(history)
    os.replace(tmp, path)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python3 -m chromasim.train", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset", help="dataset folder (chromasim generate)")
    p.add_argument("-o", "--out", required=True, help="run folder: checkpoints, history")
    p.add_argument("--train-splits", nargs="+", help="splits to train on (default: train, else all)")
    p.add_argument("--val-splits", nargs="+", help="validation splits (default: test, if any)")
    p.add_argument("--val-dataset", help="validate on this dataset instead (e.g. seed000_validation)")
    p.add_argument("--target", default="grasp", help="grasp (default), left or right")
    p.add_argument("--epochs", type=int, default=50)
    p.add_argument("--batch-size", type=int, default=64)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--weight-decay", type=float, default=1e-2)
    p.add_argument("--width", default="1.0", choices=list(WIDTHS), help="ShuffleNetV2 width")
    p.add_argument("--size", type=int, default=224, help="each fingertip image, px")
    p.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    p.add_argument("--threads", type=int, default=0,
                   help="torch CPU threads (0: every CPU this process may use)")
    p.add_argument("--workers", type=int, default=0, help="DataLoader worker processes")
    p.add_argument("--preload", action="store_true", help="decode every image once, keep in memory")
    p.add_argument("--no-augment", action="store_true")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-steps", type=int, default=0, help="stop after this many steps (0: none)")
    p.add_argument("--time-limit-min", type=float, default=0,
                   help="stop after the epoch that passes this many minutes (0: none)")
    p.add_argument("--resume", action="store_true", help="continue from RUN_DIR/checkpoint_last.pt")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    for name in ("epochs", "batch_size", "size"):
        if getattr(args, name) < 1:
            parser().error(f"--{name.replace('_', '-')} {getattr(args, name)}: must be >= 1")
    try:
        train(args)
    except DatasetError as e:
        print(f"train: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
