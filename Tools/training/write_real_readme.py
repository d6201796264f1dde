#!/usr/bin/env python3
"""Write Testing/Data/real/README.md from the training records (NAME.json) next to the models.

    python3 Tools/training/write_real_readme.py [DIR]

Run it again after adding models (e.g. the paper-size ones from train_paper_models.sh).
Standard library only.
"""

import glob
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))

HEAD = """# Real-data INR models

INRs fitted to real time-varying data (Docs/DATA.md has the sources, provenance and licences):
Gerris CFD simulations of 3D flow past a finite cylinder and past a sphere beside a plate, and
a real MR head scan animated by a mass-conserving compression + torsion. Each model was
trained by `Tools/training/train.py` in the state_dict layout of its architecture's official
implementation (`Tools/python/inr_torch_layouts.py`) and converted by
`Tools/python/inr_export.py`.

Per model: `NAME.inr` (the model), `NAME.json` (full training record: data set and its
sha256, architecture, settings, steps, PSNR, ranges, command), `NAME.tf.json` (a suggested
transfer function as a ParaView colour-map preset with `RGBPoints` and opacity `Points`;
import it in the colour-map editor, or read it in scripts).

PSNR: reconstruction of the training data at its grid samples, peak = data max - min (the
whole series), measured in float32 after training (`psnr_points` in the record says how many
grid samples were used). Every exported file was re-read with the numpy reference evaluator and
compared with PyTorch at random world points (`file_vs_torch_max_abs_diff`).

Coordinates: world bounds as in the data (Gerris box units, or mm for the head); the network
inputs are cell-centred (`centering: cell`, first/last sample centre at -1/+1); time maps
the first/last snapshot to -1/+1 (`time_steps` lists the snapshots).

Reproduce:

```sh
# data (Docs/DATA.md), then the small CPU siblings shipped here:
/usr/bin/python3 Tools/training/train.py --config small --minutes 4
# paper-size models (one GPU, ~8 min for all):
Tools/training/train_paper_models.sh OUTDIR
python3 Tools/training/write_real_readme.py      # regenerate this file
```

Timed training on a shared CPU is not bit-reproducible (the step count depends on speed);
`--steps N` is.

Paper-size models (SIREN 4->256x5->1 on both flows, Reed FFN 6x256 on the head, CoordNet
48/6 on the cylinder velocity; 1.0-2.2 MB each) come from `train_paper_models.sh` on a GPU:
copy `OUTDIR/*.inr *.json *.tf.json` here and rerun `write_real_readme.py`. The datasets it
reads (`.data/`, ~33 MB) are made by `Tools/data/make_all.sh`.

Check that every model loads and evaluates in the C++ CLI like the numpy reference:

```sh
/usr/bin/python3 Tools/training/check_cli.py build/Tools/inr Testing/Data/real
build/Tools/inr render Testing/Data/real/siren_sphere_plate_vorticity_small.inr --time 6 \
    --tf Testing/Data/real/siren_sphere_plate_vorticity_small.tf.json -o wake.png
```

"""


def fmt_range(r):
    return "[%.4g, %.4g]" % tuple(r)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    d = argv[0] if argv else os.path.join(REPO, "Testing", "Data", "real")
    recs = []
    for p in sorted(glob.glob(os.path.join(d, "*.json"))):
        b = os.path.basename(p)
        if b.endswith(".tf.json") or b.startswith("summary"):
            continue
        with open(p) as f:
            r = json.load(f)
        if "psnr_db" in r and os.path.exists(os.path.join(d, r["file"])):
            recs.append(r)
    recs.sort(key=lambda r: (r["config"] != "paper", r["name"]))
    lines = [HEAD, "## Models\n",
             "| model | config | architecture | data | size | PSNR | time range | value range |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in recs:
        lines.append("| `%s` | %s | %s (%s) | `%s` | %.1f KB | %.2f dB | %s | %s |" % (
            r["file"], r["config"], r["family"], r["layout"], r["dataset"],
            r["file_bytes"] / 1024.0, r["psnr_db"], fmt_range(r["time_range"]),
            fmt_range(r["value_range"])))
    lines.append("")
    for r in recs:
        tf = r["name"] + ".tf.json"
        note = ""
        tfp = os.path.join(d, tf)
        if os.path.exists(tfp):
            with open(tfp) as f:
                note = json.load(f)[0].get("Annotation", "")
        lines += [
            "### %s" % r["name"], "",
            "- data: `%s` (%s, %s; %d snapshots, grid %s) — %s" % (
                r["dataset"], r["quantity"], r["units"], r["snapshots"],
                " x ".join(str(v) for v in r["dataset_shape_TZYX"][:0:-1]), r["source"]),
            "- world: bounds %s (%s), time %s (%s)" % (
                r["bounds"], r["length_units"], fmt_range(r["time_range"]), r["time_units"]),
            "- architecture: %s; %d parameters, %d bytes; layout `%s` = %s" % (
                r["architecture"], r["parameters"], r["file_bytes"], r["layout"],
                r["official"]),
            "- inputs (%s), %s; output mapping: %s" % (
                ",".join(r["input_order"]), r["input_mapping"], json.dumps(r["output_mapping"])),
            "- training: %s, Adam lr %g (%s), batch %d, %d steps (%d samples) in %.0f s on %s, "
            "torch %s, seed %d" % (
                r["config"], r["lr"], r["lr_schedule"], r["batch"], r["steps"],
                r["samples_seen"], r["train_seconds"], r["device"], r["torch"], r["seed"]),
            "- PSNR %.2f dB, max abs error %.3g (over %d grid samples); value range %s" % (
                r["psnr_db"], r["max_abs_error"], r["psnr_points"], fmt_range(r["value_range"])),
            "- suggested transfer function: `%s` — %s" % (tf, note),
            ""]
    with open(os.path.join(d, "README.md"), "w") as f:
        f.write("\n".join(lines))
    print("wrote %s (%d models)" % (os.path.join(d, "README.md"), len(recs)))


if __name__ == "__main__":
    main()
