#!/usr/bin/env python3
"""Exporter error cases: each bad input must make Tools/python/inr_export.py exit non-zero
with a message that names the offending file and key (or option), and leave no output file.

    test_export_errors.py
"""

import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
import traceback
import warnings

import inr_test_util as U

torch = U.require_torch()
import inr_export  # noqa: E402
import inr_torch_layouts as L  # noqa: E402


def export(args):
    """Runs the exporter on ARGS in this process (one PyTorch import for all the cases instead of
    one per case: ~3 s each on a 2-core machine): its exit status as the command line would give
    it and what it wrote to stderr. Every warning is shown each time, as in a fresh process."""
    buf = io.StringIO()
    with contextlib.redirect_stderr(buf), warnings.catch_warnings():
        warnings.simplefilter("always")
        try:
            rc = inr_export.main(args)
        except SystemExit as e:  # argparse's usage errors
            rc = e.code if isinstance(e.code, int) else 1
        except Exception:  # what the command line would print as a traceback, exit status 1
            traceback.print_exc(file=buf)
            rc = 1
    return rc, buf.getvalue().strip()


def export_process(args):
    """The same through the command line (`python3 inr_export.py ARGS`)."""
    cmd = [sys.executable, os.path.join(U.TOOLS, "inr_export.py")] + args
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       universal_newlines=True)
    return r.returncode, r.stderr.strip()


def main():
    torch.manual_seed(0)
    ok_all = True
    with tempfile.TemporaryDirectory() as tmp:
        def save(sd, name):
            p = os.path.join(tmp, name)
            torch.save(sd, p)
            return p

        siren = L.SirenNotebook(4, 16, 1).state_dict()
        coord = L.CoordNet(4, 1, 8, 1).state_dict()
        neur = L.NeurcompFieldNet(3, [12] * 3).state_dict()
        reed = L.ReedFFN(3, 8, 1.0).state_dict()

        sd = dict(siren)
        del sd["net.1.linear.weight"]
        p_siren_missing = save(sd, "siren_missing.pth")
        sd = dict(siren)
        sd["net.1.linear.weight"] = torch.zeros(16, 15)
        p_siren_shape = save(sd, "siren_shape.pth")
        sd = dict(coord)
        del sd["net.0.transform.linear.weight"]
        del sd["net.0.transform.linear.bias"]
        p_coord_missing = save(sd, "coord_missing.pth")
        sd = dict(neur)
        del sd["net_layers.2.linear_2.weight"]
        p_neur_missing = save(sd, "neur_missing.pth")
        sd = dict(neur)
        sd["net_layers.1.linear_1.bias"] = torch.zeros(11)
        p_neur_shape = save(sd, "neur_shape.pth")
        p_reed = save(reed, "reed.pth")
        bad_b = os.path.join(tmp, "badB.npy")
        import numpy as np
        np.save(bad_b, np.zeros((3, 5), np.float32))
        sd = dict(siren)
        sd["net.0.linear.bias"] = sd["net.0.linear.bias"].clone()
        sd["net.0.linear.bias"][3] = float("nan")
        p_nan = save(sd, "siren_nan.pth")
        sd = dict(siren)
        sd["extra.weight"] = torch.zeros(3)
        p_extra = save(sd, "siren_extra.pth")
        two = L.SirenNotebook(4, 16, 1, out_features=2).state_dict()
        p_two = save(two, "siren_two_outputs.pth")
        p_siren = save(siren, "siren_ok.pth")
        spec = os.path.join(tmp, "spec.json")
        with open(spec, "w") as f:
            json.dump({"layers": [{"type": "linear", "weight": "net.0.linear.weight",
                                   "bias": "net.0.linear.bias"}, {"type": "sine"},
                                  {"type": "linear", "weight": "net.9.weight",
                                   "bias": None}]}, f)
        table = os.path.join(tmp, "table.txt")
        with open(table, "w") as f:
            f.write("0 0 1\n5 0 1\n3 0 1\n")
        p_coord = save(coord, "coord_ok.pth")
        p_neur = save(neur, "neur_ok.pth")
        good_table = os.path.join(tmp, "good_table.txt")
        with open(good_table, "w") as f:
            f.write("0 -2 5\n1 -1 7\n")
        good_b = os.path.join(tmp, "goodB.npy")
        np.save(good_b, np.ones((3, 8), np.float32))
        # nn.DataParallel keys, and a sub-module under it
        p_parallel = save({"module." + k: v for k, v in siren.items()}, "siren_parallel.pth")
        p_nested = save({"module.inr." + k: v for k, v in siren.items()}, "siren_nested.pth")
        # truncated zip containers: torch says "failed finding central directory" for a small
        # file, "[Errno 22] Invalid argument" for one past ~50 kB
        p_trunc = save(siren, "siren_truncated.pth")
        p_trunc_big = save(L.SirenNotebook(4, 64, 3).state_dict(), "siren_big_truncated.pth")
        for p in (p_trunc, p_trunc_big):
            raw = open(p, "rb").read()
            with open(p, "wb") as f:
                f.write(raw[:len(raw) * 2 // 3])
        p_trunc_legacy = os.path.join(tmp, "siren_truncated_legacy.pth")
        torch.save(siren, p_trunc_legacy, _use_new_zipfile_serialization=False)
        raw = open(p_trunc_legacy, "rb").read()
        with open(p_trunc_legacy, "wb") as f:
            f.write(raw[:len(raw) // 2])

        # training checkpoints: optimiser state, counters, EMA copies (an entry of their own or
        # the same keys under a prefix), a whole pickled module
        model = L.SirenNotebook(4, 16, 1)
        adam = torch.optim.Adam(model.parameters())
        sum(q.square().sum() for q in model.parameters()).backward()
        adam.step()
        ema = L.SirenNotebook(4, 16, 1).state_dict()
        p_ckpt = save({"epoch": 7, "state_dict": model.state_dict(), "optimizer": adam.state_dict()},
                      "siren_checkpoint.pth")
        p_ema_entry = save({"model": siren, "ema": ema, "optimizer": adam.state_dict()},
                           "siren_ema_entry.pth")
        p_ema_keys = save(dict(siren, **{"ema." + k: v for k, v in ema.items()}), "siren_ema_keys.pth")
        sd = dict(siren, **{"ema." + k: v for k, v in ema.items()})
        sd["ema.net.0.linear.weight"] = torch.zeros(16, 3)
        p_ema_bad = save(sd, "siren_ema_mismatch.pth")
        p_lightning = save({"state_dict": {"model." + k: v for k, v in siren.items()},
                            "optimizer_states": [adam.state_dict()], "global_step": 10},
                           "siren_lightning.pth")
        p_two_sd = save({"student": siren, "teacher": ema}, "siren_two_state_dicts.pth")
        p_no_tensors = save({"epoch": 3, "optimizer": adam.state_dict()}, "no_tensors.pth")
        p_module = save(model, "siren_module.pth")
        # a whole module whose class cannot be imported where the file is read
        with open(os.path.join(tmp, "lost_module.py"), "w") as f:
            f.write("import torch\nclass Net(torch.nn.Module):\n    def __init__(self):\n"
                    "        super().__init__()\n        self.fc = torch.nn.Linear(4, 1)\n")
        sys.path.insert(0, tmp)
        import lost_module
        p_lost = save(lost_module.Net(), "lost_module.pth")
        sys.path.remove(tmp)
        del sys.modules["lost_module"]
        os.remove(os.path.join(tmp, "lost_module.py"))

        out = os.path.join(tmp, "out.inr")
        # (name, args, strings that must appear in the message)
        cases = [
            ("missing key", ["siren-notebook", p_siren_missing, out],
             ["siren_missing.pth", "'net.1.linear.weight'", "missing"]),
            ("wrong shape", ["siren-notebook", p_siren_shape, out],
             ["siren_shape.pth", "'net.1.linear.weight'", "[16, 15]"]),
            ("coordnet missing transform", ["coordnet", p_coord_missing, out],
             ["coord_missing.pth", "'net.0.transform.linear.weight'"]),
            ("neurcomp missing key", ["neurcomp", p_neur_missing, out],
             ["neur_missing.pth", "'net_layers.2.linear_2.weight'"]),
            ("neurcomp wrong bias shape", ["neurcomp", p_neur_shape, out],
             ["neur_shape.pth", "'net_layers.1.linear_1.bias'", "[11]"]),
            ("wrong layout", ["coordnet", p_siren, out],
             ["siren_ok.pth", "'net.0.net.0.linear.weight'"]),
            ("reed without B", ["reed-ffn", p_reed, out], ["reed.pth", "--fourier-B"]),
            ("reed bad B", ["reed-ffn", p_reed, out, "--fourier-B", bad_b],
             ["badB.npy", "[3, 5]"]),
            ("NaN weight", ["siren-notebook", p_nan, out],
             ["siren_nan.pth", "'net.0.linear.bias'", "NaN"]),
            ("extra key", ["siren-notebook", p_extra, out], ["siren_extra.pth", "'extra.weight'"]),
            ("two outputs", ["siren-notebook", p_two, out], ["siren_two_outputs.pth", "outputs"]),
            ("generic unknown key", ["generic", p_siren, out, "--layers", spec],
             ["siren_ok.pth", "'net.9.weight'"]),
            ("no such file", ["siren-notebook", os.path.join(tmp, "nope.pth"), out],
             ["nope.pth", "no such file"]),
            ("bad per-time table", ["coordnet", p_coord, out, "--per-time-table", table],
             ["table.txt", "increase"]),
            ("cell without resolution", ["siren-notebook", p_siren, out, "--centering", "cell"],
             ["--resolution"]),
            ("empty box", ["siren-notebook", p_siren, out, "--bounds", "0", "1", "0", "1",
                           "2", "2"], ["--bounds"]),
            ("input order", ["siren-notebook", p_siren, out, "--input-order", "x,y,t"],
             ["--input-order"]),
            ("B given twice", ["reed-ffn", p_reed, out, "--fourier-B", good_b, "--reed-sigma", "1"],
             ["--fourier-B", "--reed-sigma", "not both"]),
            ("truncated .pth (zip)", ["siren-notebook", p_trunc, out],
             ["siren_truncated.pth", "truncated or corrupt"]),
            ("truncated large .pth (zip)", ["siren-notebook", p_trunc_big, out],
             ["siren_big_truncated.pth", "truncated or corrupt"]),
            ("truncated .pth (legacy)", ["siren-notebook", p_trunc_legacy, out],
             ["siren_truncated_legacy.pth", "truncated or corrupt"]),
            ("prefix matches nothing", ["siren-notebook", p_siren, out, "--prefix", "inr."],
             ["siren_ok.pth", "'inr.'", "'net.0.linear.weight'"]),
            ("EMA copy of other shapes", ["siren-notebook", p_ema_bad, out],
             ["siren_ema_mismatch.pth", "'ema.net.0.linear.weight'"]),
            ("two state_dicts", ["siren-notebook", p_two_sd, out],
             ["siren_two_state_dicts.pth", "'student'", "'teacher'", "--checkpoint-key"]),
            ("no such checkpoint entry", ["siren-notebook", p_ema_entry, out, "--checkpoint-key",
                                          "swa"], ["siren_ema_entry.pth", "'swa'", "'ema'"]),
            ("checkpoint without tensors", ["siren-notebook", p_no_tensors, out],
             ["no_tensors.pth", "no tensors", "'optimizer'"]),
            ("module not importable", ["siren-notebook", p_lost, out],
             ["lost_module.pth", "lost_module", "state_dict"]),
        ]
        # The first case also through a real process: the command line's exit status and message
        # are the in-process ones.
        assert cases[0][0] == "missing key"
        expected = export(cases[0][1])
        got = export_process(cases[0][1])
        if got != expected:
            print("FAIL command line differs from in-process: %r != %r" % (got, expected))
            ok_all = False
        for name, args, needles in cases:
            rc, msg = export(args)
            bad = []
            if rc == 0:
                bad.append("exit status 0")
            bad += ["message lacks %r" % s for s in needles if s not in msg]
            if os.path.exists(out):
                bad.append("left %s behind" % out)
                os.remove(out)
            print("%s %-28s rc=%d  %s" % ("FAIL" if bad else "ok  ", name, rc,
                                          msg.splitlines()[-1] if msg else "(no message)"))
            if bad:
                print("     " + "; ".join(bad))
                ok_all = False
        # and the good inputs do export (so the failures above are about the defects); options
        # whose absence gives values other than the training data's are warned about, and the
        # warning goes away when they are given. (name, args, warnings that must / must not appear)
        per_time = "--per-time-table"
        volume_shape, output_range = "--neurcomp-volume-shape NX NY NZ", "--output-range MIN MAX"
        neur_full = ["--neurcomp-volume-shape", "9", "17", "5", "--output-range", "0", "3"]
        goods = [
            ("good siren", ["siren-notebook", p_siren, out], [], ["warning"]),
            ("good reed", ["reed-ffn", p_reed, out, "--reed-sigma", "1"], [], ["warning"]),
            ("good reed, B file", ["reed-ffn", p_reed, out, "--fourier-B", good_b], [], []),
            ("prefix module.", ["siren-notebook", p_parallel, out, "--prefix", "module."], [], []),
            ("prefix under module.", ["siren-notebook", p_nested, out, "--prefix", "inr."], [], []),
            ("prefix module.inr.", ["siren-notebook", p_nested, out, "--prefix", "module.inr."],
             [], []),
            ("training checkpoint", ["siren-notebook", p_ckpt, out],
             ["'state_dict'", "'optimizer'", "'epoch'"], ["warning"]),
            ("EMA entry beside the model", ["siren-notebook", p_ema_entry, out],
             ["'model'", "'ema'", "--checkpoint-key"], []),
            ("EMA entry chosen", ["siren-notebook", p_ema_entry, out, "--checkpoint-key", "ema"],
             [], []),
            ("EMA copy under ema.", ["siren-notebook", p_ema_keys, out], ["'ema.'", "--prefix"], []),
            ("EMA copy chosen", ["siren-notebook", p_ema_keys, out, "--prefix", "ema."], [],
             ["ema."]),
            ("Lightning checkpoint", ["siren-notebook", p_lightning, out, "--prefix", "model."],
             ["'state_dict'", "'optimizer_states'"], []),
            ("pickled module", ["siren-notebook", p_module, out], [], []),
            ("coordnet without table", ["coordnet", p_coord, out], [per_time, "normalised"], []),
            ("coordnet with table", ["coordnet", p_coord, out, per_time, good_table], [],
             ["warning"]),
            ("neurcomp --bounds only", ["neurcomp", p_neur, out, "--bounds", "0", "8", "0", "16",
                                        "0", "4"], [volume_shape, "--bounds", output_range], []),
            ("neurcomp complete", ["neurcomp", p_neur, out] + neur_full, [], ["warning"]),
        ]
        for name, args, must, must_not in goods:
            rc, msg = export(args)
            bad = [] if rc == 0 else ["exit status %d" % rc]
            bad += ["message lacks %r" % w for w in must if w not in msg]
            bad += ["message has %r" % w for w in must_not if w in msg]
            print("%s %-28s rc=%d" % ("FAIL" if bad else "ok  ", name, rc))
            if bad:
                print("     " + "; ".join(bad) + "\n     " + msg.replace("\n", "\n     "))
                ok_all = False
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
