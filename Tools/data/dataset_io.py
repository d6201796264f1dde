"""Time-varying volume datasets on disk: ``NAME.npy`` + ``NAME.json``.

``NAME.npy``  float16 or float32 array shaped [T, Z, Y, X] (x fastest, C order).
``NAME.json`` sidecar (all lengths in the dataset's world units)::

    {"name": ..., "quantity": ..., "units": ..., "length_units": ...,
     "time_units": ..., "shape": [T, Z, Y, X], "dtype": "float16",
     "bounds": [xmin, xmax, ymin, ymax, zmin, zmax],
     "centering": "cell",            # samples at the centres of the X*Y*Z cells of bounds
     "resolution": [X, Y, Z],
     "times": [t_0, ..., t_{T-1}], "time_range": [t_0, t_{T-1}],
     "value_range": [min, max], "source": ..., "licence": ..., "generator": ...}

With ``"centering": "cell"`` the sample (i, j, k) sits at
``x = xmin + (i + 0.5) * (xmax - xmin) / X`` (and likewise y, z): exactly the convention of
Docs/FORMAT.md ``"centering": "cell"``, so an INR trained on these samples with the first and
last centre at -1 / +1 exports with ``bounds``, ``centering: cell`` and ``resolution``.

Only numpy and the standard library are needed (the GPU machine has nothing else).
"""

import json
import os

import numpy as np


def save(outdir, name, data, meta):
    """Write ``data`` [T, Z, Y, X] and its sidecar; returns the .npy path."""
    data = np.asarray(data)
    if data.ndim != 4:
        raise ValueError("dataset %s: expected [T, Z, Y, X], got shape %s" % (name, data.shape))
    if not np.all(np.isfinite(data)):
        raise ValueError("dataset %s: contains NaN/Inf" % name)
    os.makedirs(outdir, exist_ok=True)
    m = dict(meta)
    m["name"] = name
    m["shape"] = list(data.shape)
    m["dtype"] = str(data.dtype)
    T, Z, Y, X = data.shape
    m.setdefault("centering", "cell")
    m["resolution"] = [X, Y, Z]
    times = [float(t) for t in m["times"]]
    if len(times) != T:
        raise ValueError("dataset %s: %d times for %d snapshots" % (name, len(times), T))
    m["times"] = times
    m["time_range"] = [times[0], times[-1]]
    d32 = data.astype(np.float32)
    m["value_range"] = [float(d32.min()), float(d32.max())]
    m["per_time_min"] = [float(v) for v in d32.reshape(T, -1).min(axis=1)]
    m["per_time_max"] = [float(v) for v in d32.reshape(T, -1).max(axis=1)]
    path = os.path.join(outdir, name + ".npy")
    np.save(path, data)
    with open(os.path.join(outdir, name + ".json"), "w") as f:
        json.dump(m, f, indent=1)
        f.write("\n")
    return path


def load(path_or_name, datadir=None):
    """Return (data [T,Z,Y,X] as stored, meta dict). Accepts NAME, NAME.npy or NAME.json."""
    p = path_or_name
    if datadir and not os.path.isabs(p) and not os.path.exists(p):
        p = os.path.join(datadir, p)
    base = p[:-4] if p.endswith(".npy") else p[:-5] if p.endswith(".json") else p
    with open(base + ".json") as f:
        meta = json.load(f)
    data = np.load(base + ".npy", mmap_mode="r")
    if list(data.shape) != list(meta["shape"]):
        raise ValueError("%s: array shape %s, sidecar says %s" % (base, data.shape, meta["shape"]))
    return data, meta


def cell_centres(lo, hi, n):
    """World coordinates of the centres of n cells spanning [lo, hi]."""
    h = (hi - lo) / float(n)
    return lo + (np.arange(n) + 0.5) * h
