"""Rendering under MPI (issues 16 and 51): `mpirun -np N pvbatch pv_mpi_render.py` for each N
given, with the ranks sharing pixels or samples (--split, the Rank Split property), then checks
against the single-rank run:
  - the converged images agree >= --min-psnr dB, without and with shadows, measured over the
    pixels that show the volume (where either image differs from the background);
  - every rank rendered (one line per rank in Ranks In Use) and drew about 1/N of the single-rank
    queries (within --balance, relative): 1/N of the pixels of every frame, or every pixel of 1/N
    of the frames (each rank's own frames: --frames / N);
  - the ranks' queries add up to the single-rank total (within --balance / 2: neither split adds
    work; exactly, for sample shares with --no-refine: the ranks then draw one renderer's random
    numbers).

  /usr/bin/python3 run_mpi_split.py --mpirun mpirun --pvbatch pvbatch --model M.inr --out DIR --ranks 1 2 4
      [--split pixels|samples] [--no-refine]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--mpirun", required=True)
ap.add_argument("--pvbatch", required=True)
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
ap.add_argument("--frames", type=int, default=64)
ap.add_argument("--min-psnr", type=float, default=40.0)
ap.add_argument("--balance", type=float, default=0.25)
ap.add_argument("--split", choices=["pixels", "samples"], default="pixels")
ap.add_argument("--no-refine", action="store_true", help="Refine Macrocells off (pv_mpi_render.py)")
args = ap.parse_args()

import numpy as np  # noqa: E402

here = os.path.dirname(os.path.abspath(__file__))
check = C.Checks()


def run(n):
    out = os.path.join(args.out, f"np{n}")
    cmd = [args.mpirun, "-np", str(n), args.pvbatch, "--force-offscreen-rendering",
           os.path.join(here, "pv_mpi_render.py"), "--model", args.model, "--out", out,
           "--frames", str(args.frames), "--split", args.split] + (["--no-refine"] if args.no_refine else [])
    for attempt in range(3):  # only the X connection race of ranks opening the display at once
        t0 = time.time()
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        log = p.stdout
        if p.returncode == 0 or "bad X server connection" not in log:
            break
        print(f"np {n}: X connection race, retrying")
    print(f"---- mpirun -np {n} ({time.time() - t0:.1f} s, exit {p.returncode})")
    print("\n".join(l for l in log.splitlines() if l.startswith(("ok:", "FAIL:", "RESULT", "shadows", "rank ", "camera move"))))
    if p.returncode != 0:
        print(log[-4000:])
    check(p.returncode == 0, f"mpirun -np {n} pvbatch passed its own checks")
    path = os.path.join(out, "ranks.json")
    return json.load(open(path)) if os.path.exists(path) else None


def volume_psnr(a, b, background):
    mask = (np.abs(a - background).max(axis=2) > 2) | (np.abs(b - background).max(axis=2) > 2)
    if not mask.any():
        return 0.0, 0
    mse = float(np.mean((a[mask] - b[mask]) ** 2))
    return (999.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)), int(mask.sum())


reports = {n: run(n) for n in args.ranks}
base_n = min(args.ranks)
base = reports.get(base_n)
check(base is not None, f"the {base_n}-rank run wrote its report")
for n, rep in reports.items():
    if rep is None or base is None:
        continue
    for r, r0 in zip(rep["renders"], base["renders"]):
        s = r["shadows"]
        ranks = r["ranks"]
        check(sorted(x["rank"] for x in ranks) == list(range(n)) and all(x["of"] == n for x in ranks),
              f"np {n}, shadows {s}: every rank reported ({len(ranks)} lines)")
        own = args.frames if args.split == "pixels" else -(-args.frames // n)
        check(all(x["state"] == "converged" and x["frames"] == own for x in ranks),
              f"np {n}, shadows {s}: every rank converged with {own} frames of its own")
        if n > 1:
            # One node, Open MPI: the node-local rank comes from MPI_Comm_split_type and equals
            # the world rank (and OMPI_COMM_WORLD_LOCAL_RANK, which it replaces as the source).
            local = [re.search(r"local rank (\d+) from (\w+)", x["backend"]) for x in ranks]
            check(all(m and int(m.group(1)) == x["rank"] and m.group(2) == "MPI_Comm_split_type"
                      for m, x in zip(local, ranks)),
                  f"np {n}, shadows {s}: each rank's local rank from MPI_Comm_split_type equals its "
                  f"rank on this node: " + ", ".join(m.group(0) if m else "none" for m in local))
        total0 = sum(x["queries"] for x in r0["ranks"])
        total = sum(x["queries"] for x in ranks)
        if n != base_n and total0 > 0:
            share = [x["queries"] / (total0 / n) for x in ranks]
            check(all(abs(q - 1) <= args.balance for q in share),
                  f"np {n}, shadows {s}: each rank's queries / (single-rank total / {n}) = "
                  + ", ".join(f"{q:.3f}" for q in share) + f" (within +-{args.balance})")
            if args.no_refine and args.split == "samples":
                # Without macrocell refinement the shares draw exactly one renderer's numbers.
                check(total == total0, f"np {n}, shadows {s}: ranks' queries add up to exactly {total} "
                      f"(one rank: {total0})")
            else:
                check(abs(total / total0 - 1) <= args.balance / 2,
                      f"np {n}, shadows {s}: ranks' queries add up to {total} vs {total0} on one rank")
            a, b = C.read_png(r["png"]), C.read_png(r0["png"])
            bg = np.array(C.BACKGROUND, dtype=np.float64) * 255.0
            p, pixels = volume_psnr(a, b, bg)
            check(pixels > 0.05 * a.shape[0] * a.shape[1], f"np {n}, shadows {s}: the volume covers {pixels} pixels")
            check(p >= args.min_psnr, f"np {n}, shadows {s}: composited image vs {base_n} rank: "
                  f"PSNR {p:.2f} dB over the volume's pixels (>= {args.min_psnr})")
sys.exit(check.report())
