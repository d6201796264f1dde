#!/usr/bin/env python3
"""PyTorch fp16 eager baseline for the evaluator benchmark: builds a torch module from an INR
Volume file's layer graph (Docs/FORMAT.md) — nn.Linear layers with fp16 weights, torch.sin /
silu / relu / ... activations, Fourier encodings, hash grids (the plain PyTorch module of
Tools/python/inr_hashgrid_torch.py, fp16 table, fp32 interpolation), residual blocks — and times batched inference
on the GPU with CUDA events (median of --reps). The same files are timed by
gpu_evaluator_benchmark, so the ratio compares the very same networks and batch.

usage: pytorch_baseline.py [--batch N] [--reps R] [--compile] [--csv FILE] MODEL.inr ...
"""
import argparse
import math
import os
import statistics
import sys

import torch

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "Tools", "python"))
import inr_format  # noqa: E402
import inr_hashgrid_torch  # noqa: E402


class Graph(torch.nn.Module):
    def __init__(self, layers, tensors, dims=4):
        super().__init__()
        self.steps = []
        self.mods = torch.nn.ModuleList()
        for L in layers:
            t = L["type"]
            if t == "linear":
                w = torch.from_numpy(tensors[L["weight"]].copy())
                lin = torch.nn.Linear(w.shape[1], w.shape[0], bias=L.get("bias") is not None)
                with torch.no_grad():
                    lin.weight.copy_(w)
                    if L.get("bias") is not None:
                        lin.bias.copy_(torch.from_numpy(tensors[L["bias"]].copy()))
                self.mods.append(lin)
                self.steps.append(("mod", len(self.mods) - 1))
            elif t == "fourier":
                B = torch.from_numpy(tensors[L["B"]].copy()) * L.get("frequency_scale", 2 * math.pi)
                self.register_buffer("B%d" % len(self.steps), B)
                self.steps.append(("fourier", ("B%d" % len(self.steps), L.get("include_input", "none"))))
            elif t == "hashgrid":
                fields = {k: L[k] for k in inr_hashgrid_torch.inr_hashgrid.HashGridSpec.FIELDS if k in L}
                enc = inr_hashgrid_torch.HashGridEncoding(dims, **fields)
                with torch.no_grad():
                    enc.embeddings.copy_(torch.from_numpy(tensors[L["table"]].copy()))
                self.mods.append(enc)
                self.steps.append(("hashgrid", (len(self.mods) - 1, L.get("include_input", "none"))))
            elif t == "residual":
                body = Graph(L["body"], tensors)
                short = Graph(L.get("shortcut") or [], tensors)
                self.mods.append(body)
                self.mods.append(short)
                self.steps.append(("residual", (len(self.mods) - 2, len(self.mods) - 1, L.get("scale", 1.0))))
            else:
                self.steps.append((t, L))

    def forward(self, x):
        for kind, arg in self.steps:
            if kind == "mod":
                x = self.mods[arg](x)
            elif kind == "fourier":
                B, inc = arg
                p = x @ getattr(self, B).t()
                parts = [torch.sin(p), torch.cos(p)]
                if inc == "first":
                    parts.insert(0, x)
                elif inc == "last":
                    parts.append(x)
                x = torch.cat(parts, dim=-1)
            elif kind == "hashgrid":
                m, inc = arg
                parts = [self.mods[m](x).to(x.dtype)]
                if inc == "first":
                    parts.insert(0, x)
                elif inc == "last":
                    parts.append(x)
                x = torch.cat(parts, dim=-1)
            elif kind == "residual":
                b, s, scale = arg
                x = scale * (self.mods[b](x) + self.mods[s](x))
            elif kind == "sine":
                x = torch.sin(arg.get("w0", 30.0) * x)
            elif kind in ("silu", "swish"):
                x = torch.nn.functional.silu(x)
            elif kind == "relu":
                x = torch.relu(x)
            elif kind == "sigmoid":
                x = torch.sigmoid(x)
            elif kind == "tanh":
                x = torch.tanh(x)
            elif kind == "scale":
                x = arg["factor"] * x
        return x


def bench(path, batch, reps, compile_):
    inr = inr_format.read_inr(path)
    net = Graph(inr.architecture["layers"], inr.tensors, inr.architecture["input_dim"]).cuda().half().eval()
    if compile_:
        # Every model's module runs the same forward code: without a reset, dynamo counts each
        # model's compile as a recompile of it and past its recompile limit silently runs eager.
        torch._dynamo.reset()
        net = torch.compile(net)
    x = (torch.rand(batch, inr.architecture["input_dim"], device="cuda") * 2 - 1).half()
    with torch.inference_mode():
        for _ in range(3):
            net(x)
        torch.cuda.synchronize()
        times = []
        for _ in range(reps):
            a, b = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
            a.record()
            net(x)
            b.record()
            torch.cuda.synchronize()
            times.append(a.elapsed_time(b) * 1e-3)
    return batch / statistics.median(times), inr.parameter_count()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", type=int, default=1 << 21)
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--compile", action="store_true", help="also time torch.compile")
    ap.add_argument("--csv")
    ap.add_argument("models", nargs="+")
    a = ap.parse_args()
    rows = []
    print("PyTorch %s fp16 eager on %s, batch %d, %d reps" % (torch.__version__, torch.cuda.get_device_name(), a.batch, a.reps))
    for path in a.models:
        for mode in (["eager", "compile"] if a.compile else ["eager"]):
            qps, params = bench(path, a.batch, a.reps, mode == "compile")
            name = os.path.basename(path)
            print("%-28s %-8s %9d %10.4f Gq/s" % (name, mode, params, qps / 1e9))
            sys.stdout.flush()
            rows.append((name, "torch-fp16-" + mode, params, a.batch, qps))
    if a.csv:
        with open(a.csv, "w") as f:
            f.write("model,path,parameters,batch,median_qps\n")
            for r in rows:
                f.write("%s,%s,%d,%d,%.6g\n" % r)


if __name__ == "__main__":
    main()
