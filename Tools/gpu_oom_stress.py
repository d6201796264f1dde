#!/usr/bin/env python3
"""GPU out-of-memory stress (issue 52, item 2): asks `inr render` for what does not fit while a
second process holds most of the GPU's memory, and reports how many cases were tried and survived.

    /usr/bin/python3 Tools/gpu_oom_stress.py --inr build/bin/inr --out OUT_DIR \\
        [--model M.inr ...] [--leave-free-gib 2 0.25] [--fault-positions 60] [--dry-run]

Cases, each under the memory hog (a second process that allocates through the CUDA driver until
only --leave-free-gib is free, and holds it), and the fault sweep without it:
  image_16384_shadows_shade   16384x16384 with shadows and gradient shading, --backend cuda
  macrocells_256_x64_slices   256^3 macrocells x 64 temporal slices built eagerly, --backend cuda
  several_views_models        one 8192x8192 render per model, all at once (several views/models)
  default_view_auto           1024x1024, --backend auto: fits, or runs on the CPU and says so
  fault_N                     (no hog) INR_TEST_DEVICE_ALLOCATION_FAULT=N for N = 1..: the N-th
                              device allocation fails as if out of memory, --backend cuda and auto
A case survives when every process it starts ends by itself (no signal, no timeout) and either
succeeds (exit 0; "backend:" says where it ran) or fails with exit 1 and a message saying "out of
GPU memory" and what to lower; no CUDA error other than the lack of memory; and the GPU's free
memory after it is back to its level before it (within --memory-tolerance-mib). The hog must
survive every case. Writes OUT_DIR/summary.json and prints "cases tried N, survived M".

Needs a GPU, the NVIDIA driver (libcuda.so.1, through ctypes: no other Python package) and an
`inr` built with CUDA for that GPU. --dry-run prints every command and checks the files, without
a GPU.
"""
import argparse
import ctypes
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
GIB = 1 << 30
MIB = 1 << 20


# ------------------------------------------------------------------ CUDA driver through ctypes
def driver():
    cuda = ctypes.CDLL("libcuda.so.1")
    check(cuda.cuInit(0), "cuInit")
    dev = ctypes.c_int()
    check(cuda.cuDeviceGet(ctypes.byref(dev), 0), "cuDeviceGet")
    ctx = ctypes.c_void_p()
    check(cuda.cuDevicePrimaryCtxRetain(ctypes.byref(ctx), dev), "cuDevicePrimaryCtxRetain")
    check(cuda.cuCtxSetCurrent(ctx), "cuCtxSetCurrent")
    return cuda


def check(status, what):
    if status != 0:
        raise RuntimeError("%s failed: CUresult %d" % (what, status))


def mem_info(cuda):
    free, total = ctypes.c_size_t(), ctypes.c_size_t()
    check(cuda.cuMemGetInfo_v2(ctypes.byref(free), ctypes.byref(total)), "cuMemGetInfo")
    return free.value, total.value


def run_hog(leave_free):
    """Child: allocate until `leave_free` bytes are free, print HOLDING, hold until stdin closes."""
    cuda = driver()
    held = []
    chunk = 256 * MIB
    while True:
        free, total = mem_info(cuda)
        if free <= leave_free:
            break
        size = min(chunk, free - leave_free)
        if size < MIB:
            break
        ptr = ctypes.c_uint64()
        if cuda.cuMemAlloc_v2(ctypes.byref(ptr), ctypes.c_size_t(size)) != 0:
            if chunk <= 4 * MIB:
                break
            chunk //= 2
            continue
        held.append(ptr)
    free, total = mem_info(cuda)
    print("HOLDING %d bytes in %d blocks, %d free of %d" % (total - free, len(held), free, total), flush=True)
    sys.stdin.read()  # until the parent closes it


def run_meminfo():
    free, total = mem_info(driver())
    print("%d %d" % (free, total))


def device_free(dry):
    if dry:
        return 0, 0
    # A CUDA context of its own needs memory the hog may have taken: nvidia-smi reads the free
    # memory without one.
    out = subprocess.run(["nvidia-smi", "--query-gpu=memory.free,memory.total", "--format=csv,noheader,nounits",
                          "-i", os.environ.get("CUDA_VISIBLE_DEVICES", "0").split(",")[0]],
                         stdout=subprocess.PIPE, text=True, check=True).stdout.split(",")
    return int(out[0]) << 20, int(out[1]) << 20


class Hog:
    def __init__(self, leave_free, dry):
        self.proc = None
        self.line = "(dry run)"
        if dry:
            return
        self.proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--hog", str(leave_free)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.line = self.proc.stdout.readline().strip()
        if not self.line.startswith("HOLDING"):
            raise RuntimeError("the memory hog did not start: %r" % self.line)

    def alive(self):
        return self.proc is None or self.proc.poll() is None

    def stop(self):
        if self.proc is not None:
            self.proc.stdin.close()
            self.proc.wait(timeout=60)


# ------------------------------------------------------------------------------------- cases
def render_cmd(inr, model, out_png, *extra):
    return [inr, "render", model, "-o", out_png, "--frames", "1", "--seed", "3"] + list(extra)


def judge(rc, output, timed_out):
    """(survived, why) for one process."""
    if timed_out:
        return False, "timed out"
    if rc < 0 or rc >= 128:
        return False, "ended by signal %d" % (-rc if rc < 0 else rc - 128)
    bad_cuda = [l for l in output.splitlines() if "CUDA error" in l and "cudaErrorMemoryAllocation" not in l]
    if bad_cuda:
        return False, "a CUDA error other than the lack of memory: " + bad_cuda[0][:200]
    if rc == 0:
        backend = [l for l in output.splitlines() if l.startswith("backend:")]
        return True, "rendered (%s)" % (backend[0][:160] if backend else "backend not printed")
    oom = [l for l in output.splitlines() if "out of GPU memory" in l]
    if rc == 1 and oom and any(w in oom[0] for w in ("lower", "turn", "free GPU memory")):
        return True, "refused: " + oom[0][:240]
    return False, "exit %d without an out-of-memory message: %s" % (rc, output.strip()[-240:])


def run_processes(cmds, env, timeout, dry):
    """Starts every command at once; returns [(cmd, rc, output, timed_out)]."""
    if dry:
        for c in cmds:
            print("  would run:", " ".join(c))
        return [(c, 0, "backend: (dry run)", False) for c in cmds]
    procs = [subprocess.Popen(c, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
             for c in cmds]
    results = []
    deadline = time.time() + timeout
    for c, p in zip(cmds, procs):
        try:
            out, _ = p.communicate(timeout=max(1.0, deadline - time.time()))
            results.append((c, p.returncode, out, False))
        except subprocess.TimeoutExpired:
            p.kill()
            out, _ = p.communicate()
            results.append((c, p.returncode, out, True))
    return results


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inr", default=os.path.join(ROOT, "build", "bin", "inr"))
    ap.add_argument("--model", action="append", default=[],
                    help="a model (repeatable); default: the shipped real models")
    ap.add_argument("--out", required=False, default="gpu-oom-stress")
    ap.add_argument("--leave-free-gib", type=float, nargs="+", default=[2.0, 0.25],
                    help="the hog leaves this much free, one round of cases each (default 2 0.25)")
    ap.add_argument("--fault-positions", type=int, default=60,
                    help="fault sweep: N = 1..this (0: none)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per case")
    ap.add_argument("--memory-tolerance-mib", type=float, default=64.0)
    ap.add_argument("--dry-run", action="store_true")
    ap.add_argument("--hog", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--meminfo", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.hog is not None:
        return run_hog(args.hog)
    if args.meminfo:
        return run_meminfo()

    models = args.model or [os.path.join(ROOT, "Testing", "Data", "real", m) for m in
                            ("siren_cylinder_vorticity.inr", "ffn_mri_head.inr", "coordnet_cylinder_u.inr")]
    missing = [p for p in [args.inr] + models if not os.path.exists(p)]
    if missing:
        sys.exit("gpu_oom_stress: missing: " + ", ".join(missing))
    os.makedirs(args.out, exist_ok=True)
    png = lambda name: os.path.join(args.out, name + ".png")  # noqa: E731
    first = models[0]

    rounds = []
    for gib in args.leave_free_gib:
        tag = "free%gGiB" % gib
        rounds.append((tag, int(gib * GIB), [
            ("image_16384_shadows_shade", [render_cmd(args.inr, first, png(tag + "_16384"), "--size", "16384x16384",
                                                      "--shadows", "--shade", "--backend", "cuda")]),
            ("macrocells_256_x64_slices", [render_cmd(args.inr, first, png(tag + "_mc256"), "--size", "256x256",
                                                      "--macrocells", "256", "--time-slices", "64",
                                                      "--eager-slices", "--backend", "cuda")]),
            ("several_views_models", [render_cmd(args.inr, m, png("%s_view%d" % (tag, i)), "--size", "8192x8192",
                                                 "--backend", "cuda") for i, m in enumerate(models)]),
            ("default_view_auto", [render_cmd(args.inr, first, png(tag + "_auto"), "--size", "1024x1024",
                                              "--backend", "auto")]),
        ]))
    faults = []
    for n in range(1, args.fault_positions + 1):
        for backend in ("cuda", "auto"):
            faults.append(("fault_%d_%s" % (n, backend), n,
                           [render_cmd(args.inr, first, png("fault_%d_%s" % (n, backend)), "--size", "256x192",
                                       "--shadows", "--backend", backend)]))

    records = []
    tolerance = args.memory_tolerance_mib * MIB

    def run_case(name, cmds, env, hog):
        free_before, total = device_free(args.dry_run)
        t0 = time.time()
        results = run_processes(cmds, env, args.timeout, args.dry_run)
        seconds = time.time() - t0
        free_after, _ = device_free(args.dry_run)
        verdicts = [judge(rc, out, to) for (_, rc, out, to) in results]
        survived = all(ok for ok, _ in verdicts)
        why = [w for _, w in verdicts]
        if free_after + tolerance < free_before:
            survived = False
            why.append("GPU memory not back: %d MiB free before, %d after" % (free_before // MIB, free_after // MIB))
        if hog is not None and not hog.alive():
            survived = False
            why.append("the memory hog died")
        records.append({"case": name, "survived": survived, "seconds": round(seconds, 1), "results": why,
                        "free_before_mib": free_before // MIB, "free_after_mib": free_after // MIB})
        print("%-40s %s  %s" % (name, "SURVIVED" if survived else "FAILED  ", " | ".join(why))[:600], flush=True)

    for tag, leave, cases in rounds:
        hog = Hog(leave, args.dry_run)
        print("== memory hog: %s (asked to leave %.2f GiB free)" % (hog.line, leave / GIB), flush=True)
        try:
            for name, cmds in cases:
                run_case("%s/%s" % (tag, name), cmds, dict(os.environ), hog)
        finally:
            hog.stop()
    print("== fault sweep (no hog): INR_TEST_DEVICE_ALLOCATION_FAULT=1..%d" % args.fault_positions, flush=True)
    for name, n, cmds in faults:
        env = dict(os.environ, INR_TEST_DEVICE_ALLOCATION_FAULT=str(n))
        run_case(name, cmds, env, None)

    tried = len(records)
    survived = sum(r["survived"] for r in records)
    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump({"tried": tried, "survived": survived, "cases": records}, f, indent=1)
    print("cases tried %d, survived %d%s" % (tried, survived, " (dry run)" if args.dry_run else ""))
    return 0 if survived == tried else 1


if __name__ == "__main__":
    sys.exit(main())
