#!/usr/bin/env python3
"""Convert PyTorch state_dicts of public INR implementations into INR Volume files.

Usage::

    inr_export.py LAYOUT MODEL.pth OUT.inr [domain options] [output options] [layout options]

Layouts (``--help`` lists every option):

  siren-notebook  vsitzmann/siren, explore_siren.ipynb ``Siren``: keys ``net.{i}.linear.weight``
                  / ``.bias`` (sine layers) and, with outermost_linear, a final ``net.{k}.weight``.
                  Without outermost_linear the last sine layer is the output. ``--first-w0``
                  (first_omega_0) and ``--w0`` (hidden_omega_0) default to 30.
  siren-modules   vsitzmann/siren, modules.py ``SingleBVPNet`` (keys ``net.net.{i}.0.weight``)
                  or a bare ``FCBlock`` (``net.{i}.0.weight``). Activation ``--nonlinearity``
                  (sine with w0=30 by default; relu, tanh, sigmoid); the last layer is linear
                  (SingleBVPNet always uses outermost_linear) unless ``--final-activation``.
  coordnet        stevenhan1991/TVCG23-CoordNet ``CoordNet``: ``net.{i}.net.{0,1}.linear.*`` and
                  ``net.{i}.transform.linear.*`` on width changes; out = 0.5*(body + shortcut).
                  ``CoordNetReLU`` (``net.{i}.net.{0,2}.linear.*``, final linear + tanh) is
                  detected automatically. Inputs default to (t, z, y, x); the per-time-step
                  target normalisation goes in with ``--per-time-table``.
  neurcomp        matthewberger/neurcomp ``FieldNet``: ``net_layers.0.linear.*``, residual sine
                  layers ``net_layers.{i}.linear_{1,2}.*`` (or plain ``.linear.*`` when trained
                  with --not-residual) and a final ``net_layers.{k}.weight``. ave_first /
                  ave_second follow FieldNet (i > 1, i == n_layers - 2). ``--neurcomp-volume-shape``
                  reproduces its aspect-scaled inputs; ``--output-range`` its [-1,1] scaling.
  reed-ffn        awreed/DynamicCTReconstruction ``INR_3D``: ``main.{0,2,4,6}.weight`` (1x1x1
                  Conv3d or Linear) with Swish between and a final Sigmoid, fed by Fourier
                  features [sin(2 pi B^T x), cos(2 pi B^T x)]. B is not in the state_dict: give it
                  with ``--fourier-B FILE`` (.npy/.pt, the official [channels, nf] orientation)
                  or regenerate it as the official code does with ``--reed-sigma S``
                  [``--reed-seed 0``] [``--reed-input-channels 3``].
  tcnn            tiny-cuda-nn: ``--tcnn-config CONFIG.json`` (the training config, e.g. its
                  own data/config_hash.json verbatim: ``encoding`` and ``network``, optionally
                  inside ``"otype": "NetworkWithInputEncoding"``; other top-level keys such as
                  loss and optimizer are ignored) and the parameters as its PyTorch bindings
                  save them: key ``params`` of a tcnn.NetworkWithInputEncoding state_dict (or
                  ``<name>.params`` of a module holding one), the bare tensor, or a .npy (network
                  parameters first, then the encoding's; the grid pads its output with zeros);
                  or two keys ``<a>.params`` / ``<b>.params`` of a tcnn.Encoding and a
                  tcnn.Network (told apart by size; that Network pads its input with ones, so the
                  padded inputs' weights become a first-layer bias). Fields are read as
                  tiny-cuda-nn reads them: its defaults, any letter case, network otype
                  FullyFusedMLP / MegakernelMLP / CutlassMLP / MLP (or none: MLP); encoding
                  ``HashGrid`` (or ``Grid`` of type Hash), hash CoherentPrime, interpolation
                  Linear or Smoothstep, ``fixed_point_pos`` false, ``stochastic_interpolation``
                  either (training only), ``n_levels`` or ``n_features``; activations ReLU,
                  Sigmoid, Tanh, Sine, SiLU, None. What changes the network and has no
                  counterpart here is refused by name (fixed_point_pos true, other hashes,
                  dense or tiled grids, Nearest, LeakyReLU/Exponential/Softplus/Squareplus,
                  n_output_dims other than 1, unknown fields). Inputs in [0, 1] (the default
                  --input-range and --time-input-range here); 3 or 4 inputs, found from the
                  parameter count (or ``n_input_dims`` / --input-order).
  hashgrid-torch  the plain PyTorch module of Tools/python/inr_hashgrid_torch.py
                  (``HashGridNetwork``): ``encoding.embeddings`` [entries, F] with
                  ``encoding.offsets``, then ``network.{i}.weight`` / ``.bias`` (Linear layers
                  with ``--nonlinearity`` between, relu by default). The encoding's parameters
                  come from ``--hashgrid-config JSON`` (tiny-cuda-nn's encoding fields, inline or
                  a file; ``n_input_dims`` where the table does not tell 3 from 4); the
                  offsets must match the levels they give.
  generic         any MLP: ``--layers SPEC.json`` lists the layers (the architecture JSON of
                  Docs/FORMAT.md with state_dict key names where tensors go), see below.

Generic layer spec (JSON)::

    {"input_dim": 4,                                   # optional, inferred from first layer
     "layers": [
       {"type": "fourier", "B": "enc.B", "frequency_scale": 6.283185307179586,
        "include_input": "none", "B_transpose": false},   # or "B_file": "b.npy"
       {"type": "linear", "weight": "fc1.weight", "bias": "fc1.bias"},
       {"type": "sine", "w0": 30},
       {"type": "residual", "body": [...], "shortcut": [...], "scale": 0.5},
       {"type": "linear", "weight": "out.weight", "bias": null}],
     "domain": {...}, "output": {...}, "value_range": [lo, hi],   # optional defaults
     "name": "...", "description": "..."}

Tensor keys may hold 1x1(x1) convolution weights; trailing unit dimensions are dropped.
``B_transpose: true`` means the tensor is stored [in, m] (x @ B), as most code does.
Relative ``B_file`` paths are relative to the spec file.

Domain options map world space to the network inputs exactly as Docs/FORMAT.md ``domain``
says: ``--bounds``, ``--time-range``, ``--input-range`` (2 or 6 numbers), ``--centering``
node|cell with ``--resolution``, ``--time-input-range``, ``--input-order``, ``--time-steps``.
Output options: ``--output-scale/--output-offset``, or ``--output-range LO HI`` (maps
``--network-range``, default -1 1, onto [LO, HI]), or ``--per-time-table FILE`` (lines
``t min max`` or JSON {"times","min","max"}). ``--value-range`` sets the TF hint.

Checkpoints: a bare state_dict, a pickled module, or a training checkpoint whose entry
``state_dict`` / ``model_state_dict`` / ``model`` / ``net`` / ``network`` (or its only entry holding
tensors; ``--checkpoint-key NAME`` picks another, e.g. ``ema``) is the state_dict, beside optimiser
state and counters (ignored, and named in a note). DataParallel's ``module.`` is removed; a second
copy of every used key under a prefix (an EMA kept in the same state_dict) is named in a note and
left out (``--prefix`` exports it). Every mismatch between the state_dict and the layout
(missing key, wrong shape, keys left over) is an error naming the file and the key; the exit status
is then 1 (2 for bad usage).
The written file is re-read and validated before the tool reports success.

Importable: ``main(argv)`` runs the CLI; ``convert(state_dict, layout, opts)`` returns
``(tensors, architecture, layout_defaults)``; ``load_state_dict(path, prefix)``.
"""

import argparse
import collections
import json
import math
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from inr_format import FormatError, write_inr  # noqa: E402
import inr_hashgrid  # noqa: E402

LAYOUTS = ("siren-notebook", "siren-modules", "coordnet", "neurcomp", "reed-ffn", "tcnn",
           "hashgrid-torch", "generic")


class ExportError(Exception):
    """A problem with the input state_dict or options; the message names file and key."""


# ---------------------------------------------------------------------------- state_dict
def _to_numpy(v):
    if isinstance(v, np.ndarray):
        return v
    if hasattr(v, "detach"):  # torch tensor
        return v.detach().cpu().numpy()
    return np.asarray(v)


# Checkpoint entries that hold the model's state_dict, in the order they are preferred.
_STATE_DICT_ENTRIES = ("state_dict", "model_state_dict", "model", "net", "network")


def _note(text):
    sys.stderr.write("inr_export: note: %s\n" % text)


def _is_tensor(v):
    return hasattr(v, "shape") and hasattr(v, "dtype")


def _as_state_dict(v):
    """v as a mapping of names to tensors, or None: a state_dict, or a pickled nn.Module's."""
    if hasattr(v, "state_dict") and callable(v.state_dict) and not isinstance(v, dict):
        v = v.state_dict()
    if isinstance(v, dict) and any(_is_tensor(t) for t in v.values()):
        return v
    return None


def _select_entry(obj, path, entry):
    """The state_dict in a loaded object: the object itself when it holds tensors at the top
    level, else the checkpoint entry named by ``entry`` or found among the usual names."""
    if _is_tensor(obj):  # a bare tensor: tiny-cuda-nn's flat parameter vector
        return {"params": obj}
    sd = _as_state_dict(obj)
    if not isinstance(obj, dict):
        if sd is None:
            raise ExportError("%s: does not contain a state_dict (got %s)" % (path, type(obj).__name__))
        return sd
    # Entries that are state_dicts themselves (an optimizer's state is not: its tensors sit two
    # levels down, under 'state'); the rest (epoch, step, config) is ignored.
    nested = collections.OrderedDict((str(k), _as_state_dict(v)) for k, v in obj.items()
                                     if not _is_tensor(v))
    nested = collections.OrderedDict((k, v) for k, v in nested.items() if v is not None)
    if entry is not None:
        if entry not in nested:
            raise ExportError("%s: --checkpoint-key %r: no such entry holding tensors (the "
                              "checkpoint's entries: %s)" % (path, entry, ", ".join(
                                  repr(str(k)) for k in list(obj)[:12]) or "none"))
        return nested[entry]
    if any(_is_tensor(v) for v in obj.values()):
        if nested:
            _note("%s: exporting the tensors at the top level; the checkpoint also holds %s "
                  "(--checkpoint-key NAME exports one of those)"
                  % (path, ", ".join(repr(k) for k in nested)))
        return obj
    if not nested:
        raise ExportError("%s: the checkpoint holds no tensors (entries: %s)"
                          % (path, ", ".join(repr(str(k)) for k in list(obj)[:12]) or "none"))
    chosen = next((k for k in _STATE_DICT_ENTRIES if k in nested), None)
    if chosen is None and len(nested) == 1:
        chosen = next(iter(nested))
    if chosen is None:
        raise ExportError("%s: the checkpoint holds several state_dicts, %s: choose one with "
                          "--checkpoint-key NAME" % (path, ", ".join(repr(k) for k in nested)))
    others = [k for k in obj if str(k) != chosen]
    _note("%s: exporting the checkpoint's entry %r%s" % (
        path, chosen, "" if not others else "; also there: %s%s" % (
            ", ".join(repr(str(k)) for k in others[:8]), " ..." if len(others) > 8 else "")
        + (" (--checkpoint-key NAME exports another state_dict: %s)"
           % ", ".join(repr(k) for k in nested if k != chosen) if len(nested) > 1 else "")))
    return nested[chosen]


def load_state_dict(path, prefix=None, entry=None):
    """Load a state_dict from a .pth/.pt (torch), .npz or .safetensors-like file.

    Accepts a bare state_dict, a pickled nn.Module, a bare tensor (tiny-cuda-nn's flat
    parameters, as key ``params``), or a training checkpoint: a dict whose entries are the
    state_dict (``state_dict`` / ``model_state_dict`` / ``model`` / ``net`` / ``network``, or the
    only entry holding tensors; ``entry`` names another, e.g. an EMA copy) beside optimiser state
    and counters, which are ignored (and named on stderr). A ``module.`` prefix on every key
    (nn.DataParallel) is removed. With ``prefix`` only keys starting with it (as stored, else
    after removing ``module.``) are kept, with the prefix removed.
    """
    path = str(path)
    if not os.path.exists(path):
        raise ExportError("%s: no such file" % path)
    if path.endswith(".npz"):
        obj = dict(np.load(path))
    elif path.endswith(".npy"):  # a bare parameter vector (tiny-cuda-nn's flat params)
        obj = {"params": np.load(path)}
    else:
        try:
            import torch
        except ImportError:
            raise ExportError("%s: reading .pth files needs PyTorch (python3-torch)" % path)
        try:
            try:
                obj = torch.load(path, map_location="cpu", weights_only=False)
            except TypeError:  # torch < 1.13 has no weights_only
                obj = torch.load(path, map_location="cpu")
        except Exception as e:  # noqa: BLE001 - report any unpickling failure clearly
            raise ExportError("%s: %s (torch.load: %s)" % (path, _damage(path, e), e))
    obj = _select_entry(obj, path, entry)
    sd = collections.OrderedDict()
    for k, v in obj.items():
        if not _is_tensor(v):
            continue
        sd[str(k)] = _to_numpy(v)
    def strip(d, p):
        return collections.OrderedDict((k[len(p):], v) for k, v in d.items() if k.startswith(p))

    # The prefix is matched against the keys as stored first (so --prefix module.net. works on a
    # DataParallel checkpoint), then against the keys without DataParallel's "module.".
    unwrapped = strip(sd, "module.") if sd and all(k.startswith("module.") for k in sd) else sd
    if prefix:
        sd = strip(sd, prefix) or strip(unwrapped, prefix)
        if not sd:
            raise ExportError("%s: no key starts with prefix %r (the file has e.g. %s)"
                              % (path, prefix, ", ".join(repr(k) for k in list(unwrapped)[:4])))
    else:
        sd = unwrapped
    if not sd:
        raise ExportError("%s: the state_dict holds no tensors" % path)
    return sd


def _damage(path, error=None):
    """Why torch.load could not read ``path``, in words a user can act on."""
    size = os.path.getsize(path)
    if size == 0:
        return "the file is empty"
    if isinstance(error, ImportError) or (isinstance(error, AttributeError)
                                          and "Can't get attribute" in str(error)):
        # The pickle names a class this Python cannot import (a whole module was saved, e.g.
        # torch.save(model) of a tinycudann module, instead of its state_dict).
        return ("the file pickles a Python object whose class cannot be imported here (%s): "
                "save the model's state_dict instead, torch.save(model.state_dict(), FILE), and "
                "export that" % (getattr(error, "name", None) or error))
    with open(path, "rb") as f:
        magic = f.read(4)
    if magic == b"PK\x03\x04":  # the zip container torch.save writes since PyTorch 1.6
        import zipfile
        try:
            with zipfile.ZipFile(path) as z:
                bad = z.testzip()
        except (zipfile.BadZipFile, OSError, EOFError):
            return ("the file is truncated or corrupt: an incomplete zip archive (the container "
                    "of torch.save) of %d bytes; copy or download it again" % size)
        if bad:
            return "the file is corrupt: archive member %r fails its checksum" % bad
        return "the file is a complete zip archive but not one torch.load can read"
    return ("the file is truncated or corrupt, or not a PyTorch file (%d bytes; a state_dict "
            "is written by torch.save)" % size)


class _Keys(object):
    """Hands out state_dict tensors by key, checking shapes and remembering what was used."""

    def __init__(self, sd, where):
        self.sd = sd
        self.where = where
        self.used = []
        self.tensors = collections.OrderedDict()

    def has(self, key):
        return key in self.sd

    def raw_shape(self, key):
        return tuple(self._get(key, record=False).shape)

    def _get(self, key, record=True):
        if key not in self.sd:
            raise ExportError("%s: missing key %r%s" % (self.where, key, self._hint(key)))
        a = np.asarray(self.sd[key])
        # 1x1(x1) convolutions are linear layers: drop trailing unit dimensions.
        while a.ndim > 2 and a.shape[-1] == 1:
            a = a.reshape(a.shape[:-1])
        if a.dtype.kind not in "fiu":
            raise ExportError("%s: key %r has non-numeric dtype %s" % (self.where, key, a.dtype))
        if record:
            if key in self.used:
                raise ExportError("%s: key %r used twice" % (self.where, key))
            self.used.append(key)
        return a

    def _hint(self, key):
        stem = key.rsplit(".", 2)[0]
        near = [k for k in self.sd if k.startswith(stem)][:4] or list(self.sd)[:4]
        return " (the file has e.g. %s)" % ", ".join(repr(k) for k in near) if near else ""

    def take(self, key, shape, name=None):
        """Record tensor ``key`` (checked against ``shape``, None = any) for the output file."""
        a = self._get(key)
        if shape is not None:
            ok = a.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, a.shape))
            if not ok:
                want = "[" + ", ".join("*" if s is None else str(s) for s in shape) + "]"
                raise ExportError("%s: key %r has shape %s, expected %s"
                                  % (self.where, key, list(self.sd[key].shape), want))
        if not np.all(np.isfinite(a.astype(np.float64))):
            raise ExportError("%s: key %r contains NaN or Inf" % (self.where, key))
        name = name or key
        self.tensors[name] = a.astype(np.float32)
        return name, a

    def linear(self, wkey, bkey, fan_in, bias_optional=True):
        """A linear layer from ``wkey`` [out, fan_in] and ``bkey`` [out]; returns (layer, out)."""
        wname, W = self.take(wkey, (None, fan_in) if fan_in is not None else (None, None))
        layer = {"type": "linear", "weight": wname, "bias": None}
        if bkey is not None and (self.has(bkey) or not bias_optional):
            layer["bias"], _ = self.take(bkey, (W.shape[0],))
        return layer, int(W.shape[0])

    def copies(self, left):
        """Prefixes P under which ``left`` repeats every used key with the same shape (P + key):
        second copies of the network, such as an EMA kept beside the trained weights; {} unless
        they explain every key left."""
        found, rest = collections.OrderedDict(), list(left)
        while rest and self.used:
            key = rest[0]
            prefix = next((key[:-len(u)] for u in self.used if key.endswith(u) and key != u), None)
            if prefix is None:
                return {}
            copy = [prefix + u for u in self.used]
            if any(c not in rest or np.shape(self.sd[c]) != np.shape(self.sd[u])
                   for c, u in zip(copy, self.used)):
                return {}
            found[prefix] = copy
            rest = [k for k in rest if k not in copy]
        return found

    def check_all_used(self, layout):
        left = [k for k in self.sd if k not in self.used]
        copies = self.copies(left)
        if copies:
            _note("%s: exported the %s keys %s; not the second cop%s of them under %s (an EMA? "
                  "--prefix PREFIX exports one)"
                  % (self.where, layout, ", ".join(repr(k) for k in self.used[:3])
                     + (" ..." if len(self.used) > 3 else ""), "y" if len(copies) == 1 else "ies",
                     ", ".join(repr(p) for p in copies)))
            left = []
        if left:
            raise ExportError("%s: keys not part of the %s layout: %s (wrong layout, or use "
                              "--prefix to select a sub-module)"
                              % (self.where, layout, ", ".join(repr(k) for k in left[:8])
                                 + (" ..." if len(left) > 8 else "")))


def _act(name, w0):
    if name in (None, "none", "identity"):
        return []
    if name == "sine":
        return [{"type": "sine", "w0": float(w0)}]
    if name in ("silu", "swish"):
        return [{"type": "silu"}]
    if name in ("relu", "sigmoid", "tanh"):
        return [{"type": name}]
    raise ExportError("unsupported activation %r" % name)


# ---------------------------------------------------------------------------- layouts
def _siren_notebook(K, o):
    layers, width, i = [], None, 0
    while K.has("net.%d.linear.weight" % i) or K.has("net.%d.linear.bias" % i):
        lin, width = K.linear("net.%d.linear.weight" % i, "net.%d.linear.bias" % i, width)
        if i == 0:
            in_dim = K.raw_shape("net.0.linear.weight")[1]
        layers += [lin, {"type": "sine", "w0": float(o.first_w0 if i == 0 else o.w0)}]
        i += 1
    if i == 0:
        K.linear("net.0.linear.weight", None, None)  # raises "missing key"
    if K.has("net.%d.weight" % i):  # outermost_linear=True
        lin, width = K.linear("net.%d.weight" % i, "net.%d.bias" % i, width)
        layers.append(lin)
    return in_dim, layers, {}


def _siren_modules(K, o):
    if K.has("net.net.0.0.weight"):
        p = "net.net."
    elif K.has("net.0.0.weight"):
        p = "net."
    else:
        K.linear("net.net.0.0.weight", None, None)  # raises "missing key"
    layers, width, i = [], None, 0
    in_dim = K.raw_shape(p + "0.0.weight")[1]
    while K.has("%s%d.0.weight" % (p, i)) or K.has("%s%d.0.bias" % (p, i)):
        if i > 0:
            layers += _act(o.nonlinearity or "sine", o.w0 if i > 1 else o.first_w0)
        lin, width = K.linear("%s%d.0.weight" % (p, i), "%s%d.0.bias" % (p, i), width)
        layers.append(lin)
        i += 1
    if i < 2:
        raise ExportError("%s: only %d layer(s) under %r: not a SingleBVPNet/FCBlock"
                          % (K.where, i, p))
    return in_dim, layers, {}


def _coordnet(K, o):
    relu = K.has("net.0.net.2.linear.weight")
    layers, width, i = [], None, 0
    in_dim = None
    while K.has("net.%d.net.0.linear.weight" % i) or K.has("net.%d.net.0.linear.bias" % i):
        p = "net.%d." % i
        if in_dim is None:
            in_dim = K.raw_shape(p + "net.0.linear.weight")[1]
        fan_in = width
        if relu:
            l1, w1 = K.linear(p + "net.0.linear.weight", p + "net.0.linear.bias", fan_in)
            l2, w2 = K.linear(p + "net.2.linear.weight", p + "net.2.linear.bias", w1)
            body = [l1, {"type": "relu"}, l2, {"type": "sine", "w0": float(o.w0)},
                    {"type": "relu"}]
            tkey = p + "transform.0.linear."
        else:
            l1, w1 = K.linear(p + "net.0.linear.weight", p + "net.0.linear.bias", fan_in)
            l2, w2 = K.linear(p + "net.1.linear.weight", p + "net.1.linear.bias", w1)
            body = [l1, {"type": "sine", "w0": float(o.w0)}, l2,
                    {"type": "sine", "w0": float(o.w0)}]
            tkey = p + "transform.linear."
        block_in = K.raw_shape(p + "net.0.linear.weight")[1]
        shortcut = []
        if K.has(tkey + "weight"):
            lt, wt = K.linear(tkey + "weight", tkey + "bias", block_in)
            if wt != w2:
                raise ExportError("%s: key %r has %d outputs, the block body %d"
                                  % (K.where, tkey + "weight", wt, w2))
            shortcut = [lt, {"type": "relu"} if relu else {"type": "sine", "w0": float(o.w0)}]
        elif block_in != w2:
            raise ExportError("%s: missing key %r (block %d changes width %d -> %d)"
                              % (K.where, tkey + "weight", i, block_in, w2))
        layers.append({"type": "residual", "body": body, "shortcut": shortcut, "scale": 0.5})
        width = w2
        i += 1
    if i == 0:
        K.linear("net.0.net.0.linear.weight", None, None)  # raises "missing key"
    if relu:  # CoordNetReLU ends with LinearLayer + Tanh
        lin, width = K.linear("net.%d.linear.weight" % i, "net.%d.linear.bias" % i, width)
        layers += [lin, {"type": "tanh"}]
    return in_dim, layers, {"input_order": ["t", "z", "y", "x"]}


def _neurcomp(K, o):
    n = 0
    while any(K.has("net_layers.%d.%s" % (n, s)) for s in (
            "linear.weight", "linear.bias", "linear_1.weight", "linear_1.bias", "linear_2.weight",
            "weight", "bias")):
        n += 1
    if n == 0:
        K.linear("net_layers.0.linear.weight", None, None)  # raises "missing key"
    if n < 2:
        K.linear("net_layers.1.weight", None, None)  # raises "missing key"
    layers, width = [], None
    in_dim = None
    for i in range(n):
        p = "net_layers.%d." % i
        if i == n - 1:
            lin, width = K.linear(p + "weight", p + "bias", width)
            layers.append(lin)
        elif K.has(p + "linear.weight") or K.has(p + "linear.bias"):
            lin, width = K.linear(p + "linear.weight", p + "linear.bias", width)
            layers += [lin, {"type": "sine", "w0": float(o.first_w0 if i == 0 else o.w0)}]
        elif any(K.has(p + k) for k in ("linear_1.weight", "linear_1.bias", "linear_2.weight")):
            if i == 0:
                raise ExportError("%s: key %r: the first neurcomp layer must be a SineLayer "
                                  "(net_layers.0.linear.*)" % (K.where, p + "linear_1.weight"))
            l1, w1 = K.linear(p + "linear_1.weight", p + "linear_1.bias", width)
            l2, w2 = K.linear(p + "linear_2.weight", p + "linear_2.bias", w1)
            if w1 != width or w2 != width:
                raise ExportError("%s: key %r: residual sine layers keep the width (%d)"
                                  % (K.where, p + "linear_1.weight", width))
            body = ([{"type": "scale", "factor": 0.5}] if i > 1 else []) + [
                l1, {"type": "sine", "w0": float(o.w0)}, l2, {"type": "sine", "w0": float(o.w0)}]
            layers.append({"type": "residual", "body": body, "shortcut": [],
                           "scale": 0.5 if i == n - 2 else 1.0})
        else:
            raise ExportError("%s: missing key %r (or %r)" % (K.where, p + "linear.weight",
                                                             p + "linear_1.weight"))
        if i == 0:
            in_dim = K.raw_shape(p + "linear.weight")[1]
    defaults = {}
    if o.neurcomp_volume_shape:
        shp = [int(v) for v in o.neurcomp_volume_shape]
        if any(v < 2 for v in shp):
            raise ExportError("--neurcomp-volume-shape entries must be >= 2")
        m = float(max(v - 1 for v in shp))
        defaults["input_range"] = [[-(v - 1) / m, (v - 1) / m] for v in shp]
        defaults["bounds"] = [0.0, shp[0] - 1.0, 0.0, shp[1] - 1.0, 0.0, shp[2] - 1.0]
    return in_dim, layers, defaults


def _load_matrix(path, key_hint="B"):
    path = str(path)
    if not os.path.exists(path):
        raise ExportError("%s: no such file (Fourier B matrix)" % path)
    if path.endswith(".npy"):
        return np.load(path)
    if path.endswith(".txt"):
        return np.loadtxt(path, ndmin=2)
    try:
        import torch
    except ImportError:
        raise ExportError("%s: reading a torch file needs PyTorch" % path)
    obj = torch.load(path, map_location="cpu")
    if isinstance(obj, dict):
        cands = [k for k in obj if k == key_hint or k.endswith("." + key_hint)]
        if len(cands) != 1:
            raise ExportError("%s: expected a tensor or a dict with one %r entry, found keys %s"
                              % (path, key_hint, list(obj)[:8]))
        obj = obj[cands[0]]
    return _to_numpy(obj)


def _reed_ffn(K, o):
    idx = sorted(int(m.group(1)) for m in (re.match(r"main\.(\d+)\.weight$", k) for k in K.sd)
                 if m)
    if not idx:
        K.linear("main.0.weight", None, None)  # raises "missing key"
    first = K.raw_shape("main.%d.weight" % idx[0])
    if len(first) != 2 or first[1] % 2:
        raise ExportError("%s: key 'main.%d.weight' has shape %s: expected [2*nf, 2*nf(,1,1,1)]"
                          % (K.where, idx[0], list(K.sd["main.%d.weight" % idx[0]].shape)))
    nf = first[1] // 2
    if o.fourier_B and o.reed_sigma is not None:
        raise ExportError("--fourier-B and --reed-sigma both give the Fourier matrix B: use "
                          "--fourier-B FILE for the trained B, or --reed-sigma S to regenerate "
                          "it, not both")
    if o.fourier_B:
        B = np.asarray(_load_matrix(o.fourier_B), dtype=np.float64)
        if B.ndim != 2 or nf not in B.shape:
            raise ExportError("%s: B has shape %s; the network needs [channels, %d] "
                              "(nf = %d from main.%d.weight)"
                              % (o.fourier_B, list(B.shape), nf, nf, idx[0]))
        if B.shape[1] != nf:  # given as [nf, channels]: accept, it is unambiguous
            B = B.T
        provenance = "B from %s" % os.path.basename(o.fourier_B)
    else:
        if o.reed_sigma is None:
            raise ExportError("%s: reed-ffn needs the Fourier matrix: --fourier-B FILE, or "
                              "--reed-sigma S (with --reed-seed, default 0) to regenerate it "
                              "as the official code does" % K.where)
        from inr_torch_layouts import reed_fourier_matrix
        B = reed_fourier_matrix(o.reed_input_channels, nf, o.reed_sigma,
                                o.reed_seed).double().numpy()
        provenance = "B regenerated: torch.manual_seed(%d); randn((%d, %d)) * %r" % (
            o.reed_seed, o.reed_input_channels, nf, o.reed_sigma)
    K.tensors["fourier.B"] = B.T.astype(np.float32)  # our layout: [m, in]
    layers = [{"type": "fourier", "B": "fourier.B", "frequency_scale": 2.0 * math.pi,
               "include_input": "none"}]
    width = 2 * nf
    for j, i in enumerate(idx):
        if j > 0:
            layers.append({"type": "silu"})
        lin, width = K.linear("main.%d.weight" % i, "main.%d.bias" % i, width)
        layers.append(lin)
    final = o.final_activation or "sigmoid"
    layers += _act(final, o.w0)
    return B.shape[0], layers, {"_provenance": provenance}


def _generic(K, o):
    if not o.layers:
        raise ExportError("the generic layout needs --layers SPEC.json")
    try:
        with open(o.layers) as f:
            spec = json.load(f, object_pairs_hook=collections.OrderedDict)
    except (OSError, ValueError) as e:
        raise ExportError("%s: cannot read layer spec: %s" % (o.layers, e))
    base = os.path.dirname(os.path.abspath(o.layers))
    counter = [0]

    def conv(layers, width, path):
        out = []
        for n, L in enumerate(layers):
            what = "%s: %s[%d]" % (o.layers, path, n)
            if not isinstance(L, dict) or "type" not in L:
                raise ExportError("%s: each layer must be an object with 'type'" % what)
            L = collections.OrderedDict(L)
            t = L["type"]
            if t == "linear":
                extra = set(L) - {"type", "weight", "bias"}
                if extra:
                    raise ExportError("%s: unknown keys %s" % (what, sorted(extra)))
                if "weight" not in L:
                    raise ExportError("%s: linear layer needs 'weight'" % what)
                if width is None:
                    width = K.raw_shape(L["weight"])[1]
                lin, width = K.linear(L["weight"], L.get("bias"), width, bias_optional=False)
                out.append(lin)
            elif t == "fourier":
                extra = set(L) - {"type", "B", "B_file", "B_transpose", "frequency_scale",
                                  "include_input"}
                if extra:
                    raise ExportError("%s: unknown keys %s" % (what, sorted(extra)))
                if ("B" in L) == ("B_file" in L):
                    raise ExportError("%s: give exactly one of 'B' (key) or 'B_file'" % what)
                if "B" in L:
                    Bname, B = L["B"], K._get(L["B"])
                else:
                    B = _load_matrix(os.path.join(base, L["B_file"]))
                    counter[0] += 1
                    Bname = "fourier%d.B" % counter[0]
                B = np.asarray(B, dtype=np.float64)
                if L.get("B_transpose", False):
                    B = B.T
                if B.ndim != 2 or (width is not None and B.shape[1] != width):
                    raise ExportError("%s: B has shape %s (as [m, in]), expected [m, %s]%s"
                                      % (what, list(B.shape), width,
                                         "" if L.get("B_transpose") else
                                         "; set \"B_transpose\": true if it is [in, m]"))
                K.tensors[Bname] = B.astype(np.float32)
                inc = L.get("include_input", "none")
                if width is None:
                    width = B.shape[1]
                layer = {"type": "fourier", "B": Bname,
                         "frequency_scale": float(L.get("frequency_scale", 2 * math.pi)),
                         "include_input": inc}
                out.append(layer)
                width = 2 * B.shape[0] + (width if inc in ("first", "last") else 0)
            elif t == "residual":
                if width is None:
                    raise ExportError("%s: a residual block cannot come first" % what)
                body, wb = conv(L.get("body", []), width, path + "[%d].body" % n)
                sc, ws = conv(L.get("shortcut") or [], width, path + "[%d].shortcut" % n)
                if wb != ws:
                    raise ExportError("%s: body ends at width %s, shortcut at %s"
                                      % (what, wb, ws))
                out.append({"type": "residual", "body": body, "shortcut": sc,
                            "scale": float(L.get("scale", 1.0))})
                width = wb
            elif t in ("sine", "silu", "relu", "sigmoid", "tanh", "identity", "scale"):
                out.append(L)
            else:
                raise ExportError("%s: unknown layer type %r" % (what, t))
        return out, width

    if "layers" not in spec:
        raise ExportError("%s: the spec needs a 'layers' list" % o.layers)
    layers, _ = conv(spec["layers"], spec.get("input_dim"), "layers")
    first = layers[0]
    in_dim = spec.get("input_dim")
    if in_dim is None:
        t = K.tensors[first["weight"] if first["type"] == "linear" else first["B"]]
        in_dim = t.shape[1]
    defaults = {k: spec[k] for k in ("domain", "output", "value_range", "name", "description",
                                     "provenance") if k in spec}
    return int(in_dim), layers, defaults


# ---------------------------------------------------------------------------- hash grids
# tiny-cuda-nn's configs, read as tiny-cuda-nn reads them (its JSON lookups take a default for
# every absent field, compare names without regard to case and map aliases onto one class). What
# changes the forward pass and this format has no counterpart for is refused by name.
_TCNN_GRID_OTYPES = {"hashgrid": "hash", "grid": "hash", "densegrid": "dense",
                     "tiledgrid": "tiled"}  # otype -> its default grid "type"
_TCNN_GRID_TYPES = {"hash": "hash", "dense": "dense", "tiled": "tiled", "tile": "tiled"}
_TCNN_HASHES = ("prime", "coherentprime", "reversedprime", "rng", "baseconvert")
# Fields tiny-cuda-nn's grid reads. stochastic_interpolation only changes the backward pass
# (training), so either value gives the same network.
_TCNN_ENCODING_FIELDS = {"otype", "type", "n_levels", "n_features", "n_grid_features",
                         "n_features_per_level", "log2_hashmap_size", "base_resolution",
                         "per_level_scale", "interpolation", "hash", "stochastic_interpolation",
                         "fixed_point_pos", "n_dims_to_encode"}
# Fields its MLPs read; n_input_dims / n_output_dims are filled in by tiny-cuda-nn itself,
# feedback_alignment (older releases) only changed training.
_TCNN_NETWORK_FIELDS = {"otype", "activation", "output_activation", "n_neurons",
                        "n_hidden_layers", "n_input_dims", "n_output_dims", "feedback_alignment"}
# otype -> the MLP tiny-cuda-nn builds (src/network.cu): no otype means "MLP".
_TCNN_NETWORKS = {"fullyfusedmlp": "FullyFusedMLP", "megakernelmlp": "FullyFusedMLP",
                  "cutlassmlp": "CutlassMLP", "mlp": "CutlassMLP"}
# tiny-cuda-nn activation -> this format's layers (tcnn's Sine is sin(x): w0 = 1; its SiLU is
# x * sigmoid(x)). LeakyReLU, Exponential, Softplus and Squareplus have no layer here.
_TCNN_ACTIVATIONS = {"none": [], "relu": [{"type": "relu"}], "sigmoid": [{"type": "sigmoid"}],
                     "tanh": [{"type": "tanh"}], "sine": [{"type": "sine", "w0": 1.0}],
                     "silu": [{"type": "silu"}]}


def _read_json_arg(text, what):
    """JSON given inline or as a file name."""
    try:
        if text.lstrip().startswith("{"):
            return json.loads(text, object_pairs_hook=collections.OrderedDict)
        with open(text) as f:
            return json.load(f, object_pairs_hook=collections.OrderedDict)
    except (OSError, ValueError) as e:
        raise ExportError("%s: cannot read %s: %s" % (text, what, e))


def _tcnn_int(d, key, default, where, section):
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v != int(v) or v < 0:
        raise ExportError("%s: %s: %s is %r; it must be a non-negative integer"
                          % (where, section, key, v))
    return int(v)


def _tcnn_bool(d, key, where, section):
    v = d.get(key, False)
    if not isinstance(v, bool):
        raise ExportError("%s: %s: %s is %r; it must be true or false" % (where, section, key, v))
    return v


def _tcnn_hashgrid(enc, dims, where):
    """A HashGridSpec from tiny-cuda-nn's encoding config; unsupported options are named."""
    if not isinstance(enc, dict):
        raise ExportError("%s: 'encoding' must be an object" % where)
    otype = enc.get("otype")
    if otype is None or str(otype).lower() not in _TCNN_GRID_OTYPES:
        raise ExportError("%s: encoding otype %r is not supported: only HashGrid (or Grid of "
                          "type Hash) is%s" % (where, otype, "; without an otype tiny-cuda-nn "
                                               "uses OneBlob" if otype is None else ""))
    extra = set(enc) - _TCNN_ENCODING_FIELDS
    if extra:
        raise ExportError("%s: encoding: unknown or unsupported fields %s (tiny-cuda-nn's grid "
                          "reads %s)" % (where, sorted(extra), ", ".join(sorted(_TCNN_ENCODING_FIELDS))))
    grid_type = str(enc.get("type", _TCNN_GRID_OTYPES[str(otype).lower()]))
    if _TCNN_GRID_TYPES.get(grid_type.lower()) != "hash":
        raise ExportError("%s: encoding otype %r (type %r) is not supported: only HashGrid (or "
                          "Grid of type Hash) is; dense and tiled grids are not"
                          % (where, otype, enc.get("type", grid_type)))
    hash_type = str(enc.get("hash", "CoherentPrime"))
    if hash_type.lower() != "coherentprime":
        raise ExportError("%s: encoding hash %r is not supported (only CoherentPrime, tiny-cuda-nn's "
                          "default)%s" % (where, enc["hash"], "" if hash_type.lower() in _TCNN_HASHES
                                          else "; tiny-cuda-nn knows no such hash either"))
    if _tcnn_bool(enc, "fixed_point_pos", where, "encoding"):
        raise ExportError("%s: encoding fixed_point_pos true is not supported: it rounds the "
                          "positions to fixed point before the lookup, which changes the "
                          "encoding's values; false (tiny-cuda-nn's default) is" % where)
    _tcnn_bool(enc, "stochastic_interpolation", where, "encoding")
    if "n_dims_to_encode" in enc and _tcnn_int(enc, "n_dims_to_encode", 0, where, "encoding") != dims:
        raise ExportError("%s: encoding n_dims_to_encode %s: the hash grid must encode every input"
                          % (where, enc["n_dims_to_encode"]))
    interpolation = str(enc.get("interpolation", "Linear")).lower()
    if interpolation == "nearest":
        raise ExportError("%s: encoding interpolation Nearest is not supported (Linear, Smoothstep)"
                          % where)
    fields = {"interpolation": interpolation}
    for key, default in (("n_features_per_level", 2), ("log2_hashmap_size", 19),
                         ("base_resolution", 16)):
        fields[key] = _tcnn_int(enc, key, default, where, "encoding")
    features = [k for k in ("n_features", "n_grid_features") if k in enc]
    if features and "n_levels" in enc:
        raise ExportError("%s: encoding gives both %s and n_levels: one determines the other, as "
                          "tiny-cuda-nn says" % (where, features[0]))
    if features:
        n = _tcnn_int(enc, features[0], 0, where, "encoding")
        if n % fields["n_features_per_level"]:
            raise ExportError("%s: encoding %s %d is not a multiple of n_features_per_level %d"
                              % (where, features[0], n, fields["n_features_per_level"]))
        fields["n_levels"] = n // fields["n_features_per_level"]
    else:
        fields["n_levels"] = _tcnn_int(enc, "n_levels", 16, where, "encoding")
    scale = enc.get("per_level_scale", 2.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)):
        raise ExportError("%s: encoding: per_level_scale is %r; it must be a number" % (where, scale))
    fields["per_level_scale"] = float(scale)
    try:
        return inr_hashgrid.HashGridSpec(dims, **fields)
    except ValueError as e:
        raise ExportError("%s: encoding: %s" % (where, e))


def _tcnn_activation(name, field, where):
    key = str(name).lower()
    if key not in _TCNN_ACTIVATIONS:
        raise ExportError("%s: network %s %r is not supported (ReLU, Sigmoid, Tanh, Sine, SiLU, "
                          "None)" % (where, field, name))
    return [dict(a) for a in _TCNN_ACTIVATIONS[key]]


def _tcnn_mlp_shapes(width, hidden, fan_in, in_alignment, out_alignment):
    """[(out, in)] of tiny-cuda-nn's MLP weight matrices for a network input of fan_in, padded
    to the alignments (16 in tiny-cuda-nn today; older CutlassMLPs used 8: the caller tries both)."""
    pad = lambda n, a: (n + a - 1) // a * a  # noqa: E731
    if hidden == 0:
        return [(pad(1, out_alignment), pad(fan_in, in_alignment))]
    return [(width, pad(fan_in, in_alignment))] + [(width, width)] * (hidden - 1) + \
        [(pad(1, out_alignment), width)]


def _tcnn_config(cfg, where):
    """The encoding and network objects of a tiny-cuda-nn config, the network normalised:
    (encoding, {"otype", "activation", "output_activation", "n_neurons", "n_hidden_layers"})."""
    if not isinstance(cfg, dict) or "encoding" not in cfg or "network" not in cfg:
        raise ExportError("%s: the config needs 'encoding' and 'network' objects" % where)
    enc, net = cfg["encoding"], cfg["network"]
    if not isinstance(net, dict):
        raise ExportError("%s: 'network' must be an object" % where)
    extra = set(net) - _TCNN_NETWORK_FIELDS
    if extra:
        raise ExportError("%s: network: unknown or unsupported fields %s (tiny-cuda-nn's MLPs "
                          "read %s)" % (where, sorted(extra), ", ".join(sorted(_TCNN_NETWORK_FIELDS))))
    otype = net.get("otype", "MLP")
    if str(otype).lower() not in _TCNN_NETWORKS:
        raise ExportError("%s: network otype %r is not supported (FullyFusedMLP or its alias "
                          "MegakernelMLP, CutlassMLP or its alias MLP)" % (where, otype))
    for holder, label in ((cfg, "config"), (net, "network")):
        if "n_output_dims" in holder and holder["n_output_dims"] != 1:
            raise ExportError("%s: %s n_output_dims is %r; INR Volume renders scalar fields "
                              "(1 output)" % (where, label, holder["n_output_dims"]))
    norm = {"otype": _TCNN_NETWORKS[str(otype).lower()],
            "activation": _tcnn_activation(net.get("activation", "ReLU"), "activation", where),
            "output_activation": _tcnn_activation(net.get("output_activation", "None"),
                                                  "output_activation", where),
            "n_neurons": _tcnn_int(net, "n_neurons", 128, where, "network"),
            "n_hidden_layers": _tcnn_int(net, "n_hidden_layers", 5, where, "network")}
    if norm["n_neurons"] < 1:
        raise ExportError("%s: network n_neurons must be at least 1" % where)
    return enc, norm


def _tcnn_parameter_keys(K):
    """The state_dict keys holding tiny-cuda-nn parameter vectors: 'params' (the module itself
    was saved) or the least nested '*.params' keys (modules holding tcnn modules)."""
    keys = [k for k in K.sd if k == "params" or k.endswith(".params")]
    if "params" in keys:
        return ["params"]
    if not keys:
        raise ExportError("%s: no tiny-cuda-nn parameters: expected key 'params' (a saved "
                          "tcnn.NetworkWithInputEncoding) or '<name>.params' keys (modules holding "
                          "tcnn.Encoding and tcnn.Network)%s" % (K.where, K._hint("params")))
    depth = min(k.count(".") for k in keys)
    top = [k for k in keys if k.count(".") == depth]
    if len(top) > 2:
        raise ExportError("%s: %d tiny-cuda-nn parameter vectors %s: choose the network's module "
                          "with --prefix NAME." % (K.where, len(top), ", ".join(repr(k) for k in top)))
    return top


def _tcnn(K, o):
    where = o.tcnn_config or "tcnn"
    if where.lstrip().startswith("{"):  # given inline: name the option, not the whole text
        where = "--tcnn-config"
    if not o.tcnn_config:
        raise ExportError("the tcnn layout needs --tcnn-config CONFIG.json (the encoding and network "
                          "of the training config)")
    cfg = _read_json_arg(o.tcnn_config, "the tiny-cuda-nn config")
    enc, net = _tcnn_config(cfg, where)
    # The number of inputs: the config's n_input_dims, else --input-order's, else the encoding's
    # n_dims_to_encode, else whichever of 3 and 4 the parameter count fits.
    dims_given = None
    if "n_input_dims" in cfg:
        dims_given = _tcnn_int(cfg, "n_input_dims", 0, where, "config")
    elif o.input_order:
        dims_given = len(o.input_order.replace(",", " ").split())
    elif isinstance(enc, dict) and "n_dims_to_encode" in enc:
        dims_given = _tcnn_int(enc, "n_dims_to_encode", 0, where, "encoding")
    layouts = []  # (dims, spec, MLP matrix shapes, MLP parameter count)
    for dims in ((dims_given,) if dims_given else (3, 4)):
        spec = _tcnn_hashgrid(enc, dims, where)
        for in_alignment, out_alignment in ((16, 16), (8, 8), (8, 16), (16, 8)):
            shapes = _tcnn_mlp_shapes(net["n_neurons"], net["n_hidden_layers"],
                                      spec.n_output_dims, in_alignment, out_alignment)
            n_net = sum(a * b for a, b in shapes)
            if not any(c[0] == dims and c[3] == n_net for c in layouts):
                layouts.append((dims, spec, shapes, n_net))
    keys = _tcnn_parameter_keys(K)
    sizes = {k: int(np.prod(K.raw_shape(k))) for k in keys}
    # One vector: tcnn.NetworkWithInputEncoding, the MLP's parameters first, then the grid's;
    # the grid pads its output to the MLP's alignment with zeros. Two: a tcnn.Encoding and a
    # tcnn.Network (told apart by their sizes); that Network reaches its alignment through an
    # identity encoding that pads with ones, so the padded inputs' weights are a first-layer bias.
    candidates = []  # (layout, network key, encoding key)
    if len(keys) == 2:
        for c in layouts:
            n_enc = c[1].entries * c[1].n_features_per_level
            for net_key, enc_key in (keys, keys[::-1]):
                if (sizes[net_key], sizes[enc_key]) == (c[3], n_enc):
                    candidates.append((c, net_key, enc_key))
        if not candidates:  # not an encoding and a network: one may hold the whole network
            keys = [k for k in keys if any(c[3] + c[1].entries * c[1].n_features_per_level
                                           == sizes[k] for c in layouts)][:1] or keys[:1]
    if len(keys) == 1:
        candidates = [(c, keys[0], None) for c in layouts
                      if c[3] + c[1].entries * c[1].n_features_per_level == sizes[keys[0]]]
    if not candidates:
        spec3 = layouts[0][1]
        raise ExportError("%s: %s parameters (%s) %s with this config (a "
                          "hash grid of %d levels over %d inputs has %d table parameters); check "
                          "n_levels, log2_hashmap_size, base_resolution, per_level_scale, n_neurons "
                          "and n_hidden_layers against the training config"
                          % (K.where, " + ".join(str(sizes[k]) for k in keys),
                             ", ".join(repr(k) for k in keys),
                             "fit neither 3 nor 4 inputs" if not dims_given
                             else "do not fit %d inputs" % dims_given,
                             spec3.n_levels, spec3.dims, spec3.entries * spec3.n_features_per_level))
    if len({c[0][0] for c in candidates}) > 1:  # every level hashed: 3 and 4 inputs fit alike
        raise ExportError("%s: the parameters fit 3 and 4 inputs alike; add \"n_input_dims\" to "
                          "the config (or give --input-order)" % where)
    (dims, spec, shapes, n_net), net_key, enc_key = candidates[0]
    if enc_key is None:
        flat = np.asarray(K._get(net_key), np.float64).ravel()
        net_params, table = flat[:n_net], flat[n_net:]
    else:
        net_params = np.asarray(K._get(net_key), np.float64).ravel()
        table = np.asarray(K._get(enc_key), np.float64).ravel()
    for key, values in ((net_key, net_params), (enc_key or net_key, table)):
        if not np.all(np.isfinite(values)):
            raise ExportError("%s: key %r contains NaN or Inf" % (K.where, key))
    K.tensors["encoding.table"] = table.reshape(spec.table_shape).astype(np.float16)
    layers = [spec.to_layer("encoding.table")]
    at, fan_in = 0, spec.n_output_dims
    for i, (rows, cols) in enumerate(shapes):
        W = net_params[at:at + rows * cols].reshape(rows, cols)
        at += rows * cols
        last = i + 1 == len(shapes)
        keep = 1 if last else rows  # of the padded outputs only the first is the field
        layer = {"type": "linear", "weight": "mlp.%d.weight" % i, "bias": None}
        if i == 0 and enc_key is not None and cols > fan_in:
            layer["bias"] = "mlp.0.bias"
            K.tensors["mlp.0.bias"] = W[:keep, fan_in:].sum(axis=1).astype(np.float32)
        K.tensors[layer["weight"]] = W[:keep, :fan_in].astype(np.float32)
        layers.append(layer)
        layers += [dict(a) for a in (net["output_activation"] if last else net["activation"])]
        fan_in = keep
    defaults = {"input_range": [0.0, 1.0],
                "domain": {"input_range": [0.0, 1.0], "time_input_range": [0.0, 1.0]},
                "_provenance": "tiny-cuda-nn %s + %s%s" % (
                    enc.get("otype"), net["otype"],
                    "" if enc_key is None else " (tcnn.Encoding %r, tcnn.Network %r)"
                    % (enc_key, net_key))}
    return dims, layers, defaults


def _hashgrid_torch(K, o):
    if not o.hashgrid_config:
        raise ExportError("the hashgrid-torch layout needs --hashgrid-config JSON (n_levels, "
                          "n_features_per_level, log2_hashmap_size, base_resolution, per_level_scale, "
                          "interpolation: the module's constructor arguments)")
    cfg = _read_json_arg(o.hashgrid_config, "the hash-grid config")
    table_shape = K.raw_shape("encoding.embeddings")
    candidates = []
    dims_given = cfg.pop("n_input_dims", None)
    if dims_given is None and o.input_order:
        dims_given = len(o.input_order.replace(",", " ").split())
    for dims in (int(dims_given),) if dims_given else (3, 4):
        spec = _tcnn_hashgrid(dict(cfg, otype=cfg.get("otype", "HashGrid")), dims, "--hashgrid-config")
        if spec.table_shape == tuple(table_shape):
            candidates.append(spec)
    if not candidates:
        spec3 = _tcnn_hashgrid(dict(cfg, otype="HashGrid"), 3, "--hashgrid-config")
        raise ExportError("%s: key 'encoding.embeddings' has shape %s, but --hashgrid-config gives %s "
                          "(3 inputs) or %s (4 inputs); check the config against the module's"
                          % (K.where, list(table_shape), list(spec3.table_shape),
                             list(_tcnn_hashgrid(dict(cfg, otype="HashGrid"), 4, "").table_shape)))
    if len(candidates) > 1:  # every level hashed: the table does not tell 3 inputs from 4
        raise ExportError("--hashgrid-config: the table fits 3 and 4 inputs alike; add "
                          "\"n_input_dims\" to the config (or give --input-order)")
    spec = candidates[0]
    if K.has("encoding.offsets"):
        offsets = [int(v) for v in np.asarray(K._get("encoding.offsets")).ravel()]
        if offsets != spec.offsets + [spec.entries]:
            raise ExportError("%s: key 'encoding.offsets' %s disagrees with tiny-cuda-nn's level sizes "
                              "for this config %s: the module sizes its levels differently, which this "
                              "format cannot represent" % (K.where, offsets[:6], (spec.offsets + [spec.entries])[:6]))
    table_name, _ = K.take("encoding.embeddings", list(spec.table_shape), name="encoding.table")
    K.tensors[table_name] = K.tensors[table_name].astype(np.float16)
    layers = [spec.to_layer(table_name)]
    idx = sorted(int(m.group(1)) for m in (re.match(r"network\.(\d+)\.weight$", k) for k in K.sd) if m)
    if not idx:
        raise ExportError("%s: no Linear layers 'network.{i}.weight'%s" % (K.where, K._hint("network.0.weight")))
    width = spec.n_output_dims
    for n, i in enumerate(idx):
        lin, width = K.linear("network.%d.weight" % i, "network.%d.bias" % i, width)
        layers.append(lin)
        if n + 1 < len(idx):
            layers += _act(o.nonlinearity or "relu", o.w0)
    defaults = {"domain": {"input_range": [0.0, 1.0], "time_input_range": [0.0, 1.0]}}
    return spec.dims, layers, defaults


_CONVERTERS = {"siren-notebook": _siren_notebook, "siren-modules": _siren_modules,
               "coordnet": _coordnet, "neurcomp": _neurcomp, "reed-ffn": _reed_ffn,
               "tcnn": _tcnn, "hashgrid-torch": _hashgrid_torch, "generic": _generic}


def convert(state_dict, layout, opts, where="<state_dict>"):
    """Map ``state_dict`` (name -> array) in ``layout`` to (tensors, architecture, defaults)."""
    if layout not in _CONVERTERS:
        raise ExportError("unknown layout %r (one of %s)" % (layout, ", ".join(LAYOUTS)))
    K = _Keys(state_dict, where)
    in_dim, layers, defaults = _CONVERTERS[layout](K, opts)
    if layout not in ("reed-ffn",) and opts.final_activation:
        layers += _act(opts.final_activation, opts.w0)
    K.check_all_used(layout)
    # final width must be 1
    last_lin = None
    for L in layers:
        if L["type"] == "linear":
            last_lin = L
    if layers and layers[-1]["type"] != "residual" and last_lin is not None:
        w = K.tensors[last_lin["weight"]].shape[0]
        if w != 1:
            raise ExportError("%s: the network has %d outputs (key %r); INR Volume renders "
                              "scalar fields (1 output)" % (where, w, last_lin["weight"]))
    return K.tensors, {"input_dim": int(in_dim), "layers": layers}, defaults


# ---------------------------------------------------------------------------- metadata
def _read_per_time_table(path):
    try:
        with open(path) as f:
            text = f.read()
    except OSError as e:
        raise ExportError("%s: cannot read per-time table: %s" % (path, e))
    try:
        if text.lstrip().startswith("{"):
            d = json.loads(text)
            times, mn, mx = d["times"], d["min"], d["max"]
        else:
            rows = [ln.split() for ln in text.splitlines()
                    if ln.strip() and not ln.lstrip().startswith("#")]
            if any(len(r) != 3 for r in rows):
                raise ValueError("each line must be 't min max'")
            times, mn, mx = ([float(r[i]) for r in rows] for i in range(3))
    except (ValueError, KeyError) as e:
        raise ExportError("%s: bad per-time table: %s" % (path, e))
    times, mn, mx = ([float(v) for v in a] for a in (times, mn, mx))
    if not times or len(mn) != len(times) or len(mx) != len(times):
        raise ExportError("%s: per-time table needs equal, non-empty columns" % path)
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ExportError("%s: per-time table times must increase strictly" % path)
    return {"times": times, "min": mn, "max": mx}


def build_domain(opts, in_dim, defaults):
    d = collections.OrderedDict(defaults.get("domain", {}))
    if opts.bounds:
        d["bounds"] = [float(v) for v in opts.bounds]
    elif "bounds" in defaults:
        d["bounds"] = defaults["bounds"]
    if "bounds" not in d:
        d["bounds"] = [-1.0, 1.0, -1.0, 1.0, -1.0, 1.0]
        sys.stderr.write("inr_export: note: no --bounds: world box = [-1,1]^3\n")
    b = d["bounds"]
    if len(b) != 6 or not (b[0] < b[1] and b[2] < b[3] and b[4] < b[5]):
        raise ExportError("--bounds needs xmin xmax ymin ymax zmin zmax with min < max")
    if opts.input_range:
        r = [float(v) for v in opts.input_range]
        if len(r) == 2:
            d["input_range"] = r
        elif len(r) == 6:
            d["input_range"] = [r[0:2], r[2:4], r[4:6]]
        else:
            raise ExportError("--input-range takes 2 or 6 numbers")
    elif "input_range" in defaults:
        d["input_range"] = defaults["input_range"]
    if opts.centering:
        d["centering"] = opts.centering
    if opts.resolution:
        d["resolution"] = [int(v) for v in opts.resolution]
    if d.get("centering") == "cell" and "resolution" not in d:
        raise ExportError("--centering cell needs --resolution NX NY NZ")
    if opts.time_range:
        d["time_range"] = [float(v) for v in opts.time_range]
    if "time_range" not in d:
        d["time_range"] = [-1.0, 1.0] if in_dim >= 4 else [0.0, 1.0]
        if in_dim >= 4:
            sys.stderr.write("inr_export: note: no --time-range: world time = network time "
                             "[-1,1]\n")
    if not d["time_range"][0] < d["time_range"][1]:
        raise ExportError("--time-range needs t0 < t1")
    if opts.time_input_range:
        d["time_input_range"] = [float(v) for v in opts.time_input_range]
    if opts.input_order:
        order = opts.input_order.replace(",", " ").split()
    else:
        order = d.get("input_order") or defaults.get("input_order") or \
            (["x", "y", "z", "t"] if in_dim == 4 else ["x", "y", "z"] if in_dim == 3 else None)
    if order is None or len(order) != in_dim:
        raise ExportError("the network has %d inputs: give --input-order with %d of x,y,z,t"
                          % (in_dim, in_dim))
    if sorted(set(order) - {"t"}) != ["x", "y", "z"] or len(set(order)) != len(order) \
            or not set(order) <= set("xyzt"):
        raise ExportError("--input-order %s: each of x, y, z once, t at most once" % order)
    d["input_order"] = list(order)
    if opts.time_steps:
        d["time_steps"] = [float(v) for v in opts.time_steps]
    return d


def build_output(opts, defaults):
    chosen = [n for n, v in (("--output-scale/--output-offset",
                              opts.output_scale is not None or opts.output_offset is not None),
                             ("--output-range", opts.output_range is not None),
                             ("--per-time-table", opts.per_time_table is not None)) if v]
    if len(chosen) > 1:
        raise ExportError("choose one of %s" % ", ".join(chosen))
    nlo, nhi = (float(v) for v in (opts.network_range or (-1.0, 1.0)))
    if nlo == nhi:
        raise ExportError("--network-range needs two different numbers")
    vr = None
    if opts.per_time_table:
        pt = _read_per_time_table(opts.per_time_table)
        pt["network_range"] = [nlo, nhi]
        out = {"per_time": pt}
        vr = [min(pt["min"]), max(pt["max"])]
    elif opts.output_range:
        lo, hi = (float(v) for v in opts.output_range)
        s = (hi - lo) / (nhi - nlo)
        out = {"scale": s, "offset": lo - s * nlo}
        vr = [min(lo, hi), max(lo, hi)]
    elif opts.output_scale is not None or opts.output_offset is not None:
        out = {"scale": 1.0 if opts.output_scale is None else float(opts.output_scale),
               "offset": 0.0 if opts.output_offset is None else float(opts.output_offset)}
    else:
        out = defaults.get("output")
    if opts.value_range:
        vr = [float(v) for v in opts.value_range]
    elif vr is None:
        vr = defaults.get("value_range")
    return out, vr


def make_parser():
    ap = argparse.ArgumentParser(
        prog="inr_export.py", formatter_class=argparse.RawDescriptionHelpFormatter,
        description=__doc__.split("\n\n", 1)[0], epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("layout", choices=LAYOUTS)
    ap.add_argument("input", help="PyTorch state_dict (.pth/.pt), .npz, or .npy (tcnn params)")
    ap.add_argument("output", help="INR Volume file to write (.inr)")
    ap.add_argument("--prefix", help="use only keys starting with this prefix (removed)")
    ap.add_argument("--checkpoint-key", metavar="NAME",
                    help="the checkpoint entry holding the state_dict to export (e.g. an EMA "
                         "copy); default: state_dict, model_state_dict, model, net, network, or "
                         "the only entry holding tensors")
    g = ap.add_argument_group("layout options")
    g.add_argument("--w0", type=float, default=30.0, help="sine frequency (hidden) [30]")
    g.add_argument("--first-w0", type=float, help="sine frequency of the first layer [--w0]")
    g.add_argument("--nonlinearity", choices=("sine", "relu", "tanh", "sigmoid", "silu"),
                   help="hidden activation: siren-modules [sine], hashgrid-torch [relu]")
    g.add_argument("--final-activation", choices=("none", "sine", "relu", "tanh", "sigmoid",
                                                  "silu"),
                   help="activation after the last layer (reed-ffn default: sigmoid)")
    g.add_argument("--neurcomp-volume-shape", nargs=3, type=int, metavar=("NX", "NY", "NZ"),
                   help="neurcomp: training volume shape; sets the aspect-scaled input range "
                        "and default bounds [0, n-1]")
    g.add_argument("--fourier-B", help="reed-ffn: B matrix file (.npy/.pt/.txt)")
    g.add_argument("--reed-sigma", type=float, help="reed-ffn: regenerate B with this sigma")
    g.add_argument("--reed-seed", type=int, default=0, help="reed-ffn: seed [0]")
    g.add_argument("--reed-input-channels", type=int, default=3,
                   help="reed-ffn: rows of B (3 = x,y,z as published; 4 adds t) [3]")
    g.add_argument("--layers", help="generic: layer spec JSON")
    g.add_argument("--tcnn-config", help="tcnn: tiny-cuda-nn config JSON (file or inline)")
    g.add_argument("--hashgrid-config",
                   help="hashgrid-torch: the encoding's parameters, JSON (file or inline)")
    g = ap.add_argument_group("domain (Docs/FORMAT.md 'domain')")
    g.add_argument("--bounds", nargs=6, type=float,
                   metavar=("XMIN", "XMAX", "YMIN", "YMAX", "ZMIN", "ZMAX"))
    g.add_argument("--time-range", nargs=2, type=float, metavar=("T0", "T1"))
    g.add_argument("--input-range", nargs="+", type=float, metavar="V",
                   help="network coordinate range: LO HI, or 3 pairs (x, y, z) [-1 1]")
    g.add_argument("--centering", choices=("node", "cell"))
    g.add_argument("--resolution", nargs=3, type=int, metavar=("NX", "NY", "NZ"))
    g.add_argument("--time-input-range", nargs=2, type=float, metavar=("LO", "HI"))
    g.add_argument("--input-order", help="e.g. 'x,y,z,t' or 't,z,y,x'")
    g.add_argument("--time-steps", nargs="+", type=float, metavar="T")
    g = ap.add_argument_group("output mapping and metadata")
    g.add_argument("--output-scale", type=float)
    g.add_argument("--output-offset", type=float)
    g.add_argument("--output-range", nargs=2, type=float, metavar=("LO", "HI"),
                   help="field values at the ends of --network-range")
    g.add_argument("--network-range", nargs=2, type=float, metavar=("LO", "HI"),
                   help="network output range for --output-range/--per-time-table [-1 1]")
    g.add_argument("--per-time-table", metavar="FILE",
                   help="per-time-step min/max table ('t min max' lines or JSON)")
    g.add_argument("--value-range", nargs=2, type=float, metavar=("LO", "HI"))
    g.add_argument("--name")
    g.add_argument("--description")
    g.add_argument("--provenance")
    g.add_argument("--dtype", default="F32", choices=("F32", "F16", "BF16", "F64"))
    g.add_argument("--quiet", action="store_true")
    return ap


# Layouts whose networks are trained on normalised targets: without an output mapping the file
# holds those normalised values, not data units.
_NORMALISED_OUTPUT = {
    "coordnet": "CoordNet is trained on targets normalised per time step, so without "
                "--per-time-table FILE (lines 't min max' of the training data) the file holds "
                "normalised values, not data units",
    "neurcomp": "FieldNet is trained on the volume scaled to [-1, 1], so without --output-range "
                "MIN MAX (the training volume's range) the file holds the network's [-1, 1], "
                "not data units",
}


def _warn_omissions(opts, output):
    """Warns about options whose absence silently gives values other than the training data's."""
    def warn(text):
        sys.stderr.write("inr_export: warning: %s: %s\n" % (opts.layout, text))
    if opts.layout in _NORMALISED_OUTPUT and output is None:
        warn(_NORMALISED_OUTPUT[opts.layout])
    if opts.layout == "neurcomp" and not opts.neurcomp_volume_shape and not opts.input_range:
        warn("no --neurcomp-volume-shape: every axis of the box%s maps onto [-1, 1], but FieldNet "
             "scales its inputs by the training volume's aspect ((n-1)/max(n-1) per axis), so a "
             "non-cubic volume comes out stretched; give --neurcomp-volume-shape NX NY NZ"
             % (" (--bounds)" if opts.bounds else ""))


def export(opts):
    """Run one export described by parsed options; returns the output path."""
    if opts.first_w0 is None:
        opts.first_w0 = opts.w0
    sd = load_state_dict(opts.input, opts.prefix, opts.checkpoint_key)
    tensors, arch, defaults = convert(sd, opts.layout, opts, where=opts.input)
    domain = build_domain(opts, arch["input_dim"], defaults)
    output, vr = build_output(opts, defaults)
    _warn_omissions(opts, output)
    prov = opts.provenance or defaults.get("provenance") or (
        "inr_export.py %s from %s%s" % (opts.layout, os.path.basename(opts.input),
                                        "; " + defaults["_provenance"]
                                        if "_provenance" in defaults else ""))
    name = opts.name or defaults.get("name") or \
        os.path.splitext(os.path.basename(opts.output))[0]
    try:
        # Hash-grid tables stay fp16, as trained (Docs/FORMAT.md "hashgrid").
        tables = {L["table"]: "F16" for L in arch["layers"] if L["type"] == "hashgrid"}
        write_inr(opts.output, tensors, arch, domain, output=output, value_range=vr, name=name,
                  description=opts.description or defaults.get("description"),
                  provenance=prov, dtype=opts.dtype, tensor_dtypes=tables)
        from inr_reference import ReferenceModel  # validate what we wrote
        ReferenceModel.load(opts.output)
    except FormatError as e:
        if os.path.exists(opts.output):
            os.remove(opts.output)
        raise ExportError("%s: %s" % (opts.output, e))
    if not opts.quiet:
        n = sum(int(np.prod(t.shape)) for t in tensors.values())
        sys.stderr.write("inr_export: wrote %s (%s, %d parameters, %d inputs %s)\n"
                         % (opts.output, opts.layout, n, arch["input_dim"],
                            ",".join(domain["input_order"])))
    return opts.output


def main(argv=None):
    opts = make_parser().parse_args(argv)
    try:
        export(opts)
    except ExportError as e:
        sys.stderr.write("inr_export: error: %s\n" % e)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
