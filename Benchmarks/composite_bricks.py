#!/usr/bin/env python3
"""Composites the bricks of `inr render --brick I/N` (premultiplied RGBA .npy, each with its
.brick.json beside it) front to back with the over operator, in the bricks' visibility order from
the camera, or the pixel shares of `inr render --pixel-share I/N` (disjoint pixels: any order):
what ParaView's ordered compositing does under MPI, for runs without ParaView (one process per
GPU); or averages the sample shares of `inr render --sample-share I/N` (every pixel, each share
its own frames), weighted by each share's frames: the mean over all their frames. Optionally
compares the composite with a whole-box render (`--brick 0/1`, or any premultiplied RGBA .npy)
over the pixels the volume covers.

  composite_bricks.py B0.npy B1.npy ... [-o OUT.png|OUT.npy] [--background R,G,B]
                      [--reference WHOLE.npy] [--min-psnr DB] [--csv FILE]

Exits 1 when --min-psnr is given and the composite's PSNR falls below it.
"""
import argparse
import csv
import json
import struct
import sys
import zlib

import numpy as np


def load_brick(path):
    if not path.endswith(".npy"):
        sys.exit(f"composite_bricks: {path}: expected a .npy brick image from inr render --brick")
    meta_path = path[:-4] + ".brick.json"
    try:
        with open(meta_path) as f:
            meta = json.load(f)
    except OSError as e:
        sys.exit(f"composite_bricks: {meta_path}: cannot read the brick description ({e.strerror})")
    image = np.load(path)
    if image.ndim != 3 or image.shape[2] != 4:
        sys.exit(f"composite_bricks: {path}: expected shape (height, width, 4), got {image.shape}")
    return image.astype(np.float64), meta


def visibility_order(boxes, eye):
    """Front-to-back order of k-d bricks from `eye`: at every cut plane the eye's side first
    (the engine's brickVisibilityOrder)."""
    order = []

    def visit(ids):
        if len(ids) == 1:
            order.append(ids[0])
            return
        for axis in range(3):
            for c in ids:
                p = boxes[c][2 * axis]
                below = [k for k in ids if boxes[k][2 * axis + 1] <= p]
                above = [k for k in ids if boxes[k][2 * axis] >= p]
                if below and above and len(below) + len(above) == len(ids):
                    first, second = (below, above) if eye[axis] < p else (above, below)
                    visit(first)
                    visit(second)
                    return
        sys.exit("composite_bricks: the bricks are not a k-d split of one box")

    visit(list(range(len(boxes))))
    return order


def eye_of(camera):
    pos, focal = np.array(camera["position"], float), np.array(camera["focal_point"], float)
    if camera.get("parallel"):
        return focal + (pos - focal) * 1e9  # the eye far back along the view direction
    return pos


def write_png(path, rgb):
    h, w, _ = rgb.shape
    raw = b"".join(b"\0" + bytes(row) for row in (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8).reshape(h, -1))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def psnr_over_volume(a, b, coverage=0.01):
    """PSNR (peak 1) of premultiplied RGBA over the pixels either image covers."""
    mask = (a[..., 3] > coverage) | (b[..., 3] > coverage)
    if not mask.any():
        return float("nan"), 0
    mse = float(((a[mask] - b[mask]) ** 2).mean())
    return (float("inf") if mse == 0 else 10 * np.log10(1.0 / mse)), int(mask.sum())


def sample_share_estimate(shares):
    """Estimated PSNR (dB) of the frame-weighted mean of sample shares from each share's own
    (frames, estimated PSNR): the shares' errors are independent, so the mean's squared error is
    the sum of each share's estimated MSE times its weight squared. A share without an estimate
    (None, or -inf: a covered pixel with one sample) leaves the mean without one."""
    total = sum(f for f, _ in shares)
    mse = 0.0
    for frames, db in shares:
        if db is None or db == float("-inf"):
            return float("-inf")
        mse += (frames / total) ** 2 * 10.0 ** (-db / 10.0)
    return float("inf") if mse == 0 else -10.0 * np.log10(mse)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bricks", nargs="+")
    ap.add_argument("-o", "--output")
    ap.add_argument("--background", default="0,0,0")
    ap.add_argument("--reference")
    ap.add_argument("--min-psnr", type=float)
    ap.add_argument("--csv")
    a = ap.parse_args()

    loaded = [load_brick(p) for p in a.bricks]
    count = loaded[0][1]["brick"]["count"]
    indices = sorted(m["brick"]["index"] for _, m in loaded)
    if indices != list(range(count)) or any(m["brick"]["count"] != count for _, m in loaded):
        sys.exit(f"composite_bricks: expected bricks 0..{count - 1} of {count} exactly once, got {indices}")
    loaded.sort(key=lambda im: im[1]["brick"]["index"])
    shapes = {im.shape for im, _ in loaded}
    if len(shapes) != 1:
        sys.exit(f"composite_bricks: the bricks' image sizes differ: {sorted(shapes)}")
    eye = eye_of(loaded[0][1]["camera"])
    splits = {m.get("split", "bricks") for _, m in loaded}
    if len(splits) != 1:
        sys.exit(f"composite_bricks: the images mix splits {sorted(splits)}")
    samples = splits == {"samples"}
    if splits <= {"pixels", "samples"}:
        order = list(range(count))  # disjoint pixels, or a weighted mean: any order
    else:
        order = visibility_order([m["box"] for _, m in loaded], eye)

    out = np.zeros_like(loaded[0][0])
    if samples:
        total_frames = sum(m["frames"] for _, m in loaded)
        for im, m in loaded:
            out += (m["frames"] / total_frames) * im
    else:
        for k in order:
            out += (1.0 - out[..., 3:4]) * loaded[k][0]

    total_queries = sum(m["queries"] + m["shadow_queries"] for _, m in loaded)
    rows = []
    print(f"{count} brick(s), front-to-back order {order}")
    print(f"{'brick':>5} {'frames':>6} {'queries':>12} {'share':>6} {'ms/frame':>9} {'seconds':>8} {'est.dB':>7}  box")
    for im, m in loaded:
        q = m["queries"] + m["shadow_queries"]
        share = q / total_queries if total_queries else 0.0
        box = ",".join(f"{v:.4g}" for v in m["box"])
        print(f"{m['brick']['index']:>5} {m['frames']:>6} {q:>12} {share:>6.3f} {m['ms_per_frame']:>9.2f} "
              f"{m['render_seconds']:>8.3f} {m['estimated_psnr_db'] or float('nan'):>7.2f}  {box}")
        rows.append({"brick": m["brick"]["index"], "count": count, "frames": m["frames"], "queries": q,
                     "share": share, "ms_per_frame": m["ms_per_frame"], "seconds": m["render_seconds"],
                     "estimated_psnr_db": m["estimated_psnr_db"], "backend": m.get("backend", "")})

    if samples:
        estimate = sample_share_estimate([(m["frames"], m["estimated_psnr_db"]) for _, m in loaded])
        print(f"sample shares: mean over {total_frames} frames; estimated PSNR of the mean {estimate:.2f} dB")
        for r in rows:
            r["composite_estimated_psnr_db"] = estimate

    psnr = None
    if a.reference:
        ref = np.load(a.reference).astype(np.float64)
        if ref.shape != out.shape:
            sys.exit(f"composite_bricks: {a.reference}: shape {ref.shape} differs from the bricks' {out.shape}")
        psnr, pixels = psnr_over_volume(out, ref)
        print(f"composite vs {a.reference}: PSNR {psnr:.2f} dB over {pixels} volume pixels")
    if a.output:
        if a.output.endswith(".npy"):
            np.save(a.output, out.astype(np.float32))
        elif a.output.endswith(".png"):
            bg = np.array([float(v) for v in a.background.split(",")])
            write_png(a.output, out[..., :3] + (1.0 - out[..., 3:4]) * bg)
        else:
            sys.exit(f"composite_bricks: -o {a.output}: expected .png or .npy")
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()) + ["psnr_vs_reference_db"])
            w.writeheader()
            for r in rows:
                w.writerow({**r, "psnr_vs_reference_db": "" if psnr is None else f"{psnr:.3f}"})
    if a.min_psnr is not None:
        if psnr is None:
            sys.exit("composite_bricks: --min-psnr needs --reference")
        if not psnr >= a.min_psnr:
            print(f"composite_bricks: FAILED: PSNR {psnr:.2f} dB < {a.min_psnr} dB", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
