"""Write and read INR Volume model files (Docs/FORMAT.md, format version 1).

An INR Volume file is a safetensors container: the network weights as tensors, and the
architecture / domain / output mapping as JSON *strings* in the safetensors ``__metadata__``
map. This module needs only numpy. When the ``safetensors`` Python package is importable it is
used for the container; otherwise the container is written and parsed by hand (the layout is
simple: ``u64 little-endian N``, ``N`` bytes of JSON header padded with spaces to a multiple of
8, then the tensor data, contiguous, in header order).

Typical use::

    from inr_format import write_inr, read_inr
    write_inr("m.inr", tensors, architecture={"input_dim": 4, "layers": [...]},
              domain={"bounds": [0, 2, -1, 1, 0, 1], "time_range": [0, 10]},
              output={"scale": 0.5, "offset": 0.5}, value_range=[0, 1], name="demo")
    model = read_inr("m.inr")   # InrFile: .tensors, .metadata, .architecture, .domain, ...
"""

import collections
import json
import struct

import numpy as np

FORMAT_NAME = "inr-volume"
FORMAT_VERSION = 1

# safetensors dtype name -> (numpy dtype or None for bf16, bytes per element)
_DTYPES = {
    "F32": (np.dtype("<f4"), 4),
    "F16": (np.dtype("<f2"), 2),
    "F64": (np.dtype("<f8"), 8),
    "BF16": (None, 2),
}
_NUMPY_TO_ST = {np.dtype("float32"): "F32", np.dtype("float16"): "F16",
                np.dtype("float64"): "F64"}

# Largest header we are willing to parse (the safetensors reference limit is 100 MB).
MAX_HEADER_BYTES = 100 * 1024 * 1024

try:  # pragma: no cover - depends on the machine
    import safetensors.numpy as _st_numpy  # type: ignore
except Exception:  # absent on Debian 12
    _st_numpy = None


class FormatError(ValueError):
    """A model file (or the data handed to the writer) violates Docs/FORMAT.md."""


def _json_dumps(obj):
    # allow_nan=False: NaN/Inf are not JSON and not allowed in the format.
    return json.dumps(obj, separators=(",", ":"), allow_nan=False)


def _to_bf16_bytes(a):
    """float32 array -> bfloat16 bytes (round to nearest even)."""
    u = np.ascontiguousarray(a, dtype="<f4").view("<u4").astype(np.uint64)
    rounding = ((u >> 16) & 1) + 0x7FFF
    return ((u + rounding) >> 16).astype("<u2").tobytes()


def _from_bf16_bytes(b, count):
    u = np.frombuffer(b, dtype="<u2", count=count).astype("<u4") << 16
    return u.view("<f4").astype(np.float32)


def build_metadata(architecture, domain, output=None, value_range=None, name=None,
                   description=None, provenance=None, extra=None):
    """Return the ``__metadata__`` map (str -> str) that Docs/FORMAT.md specifies."""
    if not isinstance(architecture, dict) or "layers" not in architecture:
        raise FormatError("architecture must be a dict with 'input_dim' and 'layers'")
    if not isinstance(domain, dict) or "bounds" not in domain or "time_range" not in domain:
        raise FormatError("domain must be a dict with at least 'bounds' and 'time_range'")
    md = collections.OrderedDict()
    md["format"] = FORMAT_NAME
    md["format_version"] = str(FORMAT_VERSION)
    md["architecture"] = _json_dumps(architecture)
    md["domain"] = _json_dumps(domain)
    if output is not None:
        md["output"] = _json_dumps(output)
    if value_range is not None:
        lo, hi = (float(v) for v in value_range)
        md["value_range"] = _json_dumps([lo, hi])
    for key, val in (("name", name), ("description", description), ("provenance", provenance)):
        if val is not None:
            md[key] = str(val)
    for key, val in (extra or {}).items():
        if key in md:
            raise FormatError("extra metadata key %r clashes with a format key" % key)
        md[key] = val if isinstance(val, str) else _json_dumps(val)
    return md


def write_safetensors(path, tensors, metadata, dtype="F32", tensor_dtypes=None):
    """Write ``tensors`` (ordered name -> array) and ``metadata`` (str -> str) to ``path``.

    Arrays are converted to ``dtype`` (F32 default; F16, BF16, F64 allowed), or to
    ``tensor_dtypes[name]`` where given (hash-grid tables stay F16, as trained). Non-finite
    values are rejected. With the hand-written container the data section holds the tensors
    contiguously in the order given.
    """
    tensor_dtypes = dict(tensor_dtypes or {})
    for dt in [dtype] + list(tensor_dtypes.values()):
        if dt not in _DTYPES:
            raise FormatError("unsupported dtype %r (use one of %s)" % (dt, ", ".join(_DTYPES)))
    arrays = collections.OrderedDict()
    for name, arr in tensors.items():
        a = np.asarray(arr)
        if a.dtype.kind not in "fiu":
            raise FormatError("tensor %r has non-numeric dtype %s" % (name, a.dtype))
        a64 = a.astype(np.float64)
        if not np.all(np.isfinite(a64)):
            raise FormatError("tensor %r contains NaN or Inf" % name)
        arrays[name] = a
    for k, v in metadata.items():
        if not isinstance(k, str) or not isinstance(v, str):
            raise FormatError("__metadata__ must map strings to strings (key %r)" % (k,))

    def dtype_of(name):
        return tensor_dtypes.get(name, dtype)

    if _st_numpy is not None and "BF16" not in [dtype_of(n) for n in arrays]:
        conv = collections.OrderedDict(
            (n, np.ascontiguousarray(a, dtype=_DTYPES[dtype_of(n)][0])) for n, a in arrays.items())
        _st_numpy.save_file(conv, str(path), metadata=dict(metadata))
        return

    header = collections.OrderedDict()
    header["__metadata__"] = collections.OrderedDict(metadata)
    blobs = []
    offset = 0
    for name, a in arrays.items():
        if name == "__metadata__":
            raise FormatError("a tensor may not be called __metadata__")
        if dtype_of(name) == "BF16":
            blob = _to_bf16_bytes(a)
        else:
            blob = np.ascontiguousarray(a, dtype=_DTYPES[dtype_of(name)][0]).tobytes()
        header[name] = collections.OrderedDict(
            [("dtype", dtype_of(name)), ("shape", [int(s) for s in a.shape]),
             ("data_offsets", [offset, offset + len(blob)])])
        blobs.append(blob)
        offset += len(blob)
    hbytes = json.dumps(header, separators=(",", ":"), allow_nan=False).encode("utf-8")
    hbytes += b" " * ((-(8 + len(hbytes))) % 8)  # data section starts 8-byte aligned
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(hbytes)))
        f.write(hbytes)
        for blob in blobs:
            f.write(blob)


def write_inr(path, tensors, architecture, domain, output=None, value_range=None, name=None,
              description=None, provenance=None, dtype="F32", extra_metadata=None,
              tensor_dtypes=None):
    """Write an INR Volume model file. ``tensors``: ordered dict name -> numpy array; the
    metadata dicts are serialised as JSON strings exactly as Docs/FORMAT.md specifies.
    ``tensor_dtypes``: per-tensor dtypes overriding ``dtype`` (see write_safetensors)."""
    md = build_metadata(architecture, domain, output, value_range, name, description,
                        provenance, extra_metadata)
    write_safetensors(path, tensors, md, dtype=dtype, tensor_dtypes=tensor_dtypes)


def read_safetensors(path):
    """Parse a safetensors file by hand, validating the container rules of Docs/FORMAT.md.

    Returns ``(tensors, metadata)``: an ordered dict name -> float32 array (in data-offset
    order) and the raw ``__metadata__`` map (str -> str).
    """
    with open(path, "rb") as f:
        data = f.read()
    where = str(path)
    if len(data) < 8:
        raise FormatError("%s: file too short for a safetensors header" % where)
    (n,) = struct.unpack("<Q", data[:8])
    if n > MAX_HEADER_BYTES or 8 + n > len(data):
        raise FormatError("%s: header length %d exceeds the file size or the limit" % (where, n))
    try:
        header = json.loads(data[8:8 + n].decode("utf-8"),
                            object_pairs_hook=collections.OrderedDict)
    except (UnicodeDecodeError, ValueError) as e:
        raise FormatError("%s: malformed JSON header: %s" % (where, e))
    if not isinstance(header, dict):
        raise FormatError("%s: header is not a JSON object" % where)
    metadata = header.pop("__metadata__", {}) or {}
    if not isinstance(metadata, dict) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in metadata.items()):
        raise FormatError("%s: __metadata__ must map strings to strings" % where)
    body = data[8 + n:]
    spans = []
    for name, info in header.items():
        if not isinstance(info, dict) or set(info) != {"dtype", "shape", "data_offsets"}:
            raise FormatError("%s: tensor %r: bad header entry" % (where, name))
        dt = info["dtype"]
        if dt not in _DTYPES:
            raise FormatError("%s: tensor %r: unsupported dtype %r" % (where, name, dt))
        shape = info["shape"]
        begin, end = info["data_offsets"]
        count = int(np.prod(shape)) if len(shape) else 1
        if not (0 <= begin <= end <= len(body)):
            raise FormatError("%s: tensor %r: offsets out of range" % (where, name))
        if end - begin != count * _DTYPES[dt][1]:
            raise FormatError("%s: tensor %r: byte size does not match shape" % (where, name))
        spans.append((begin, end, name, dt, shape, count))
    spans.sort()
    pos = 0
    tensors = collections.OrderedDict()
    for begin, end, name, dt, shape, count in spans:
        if begin != pos:
            raise FormatError("%s: tensor %r: data overlaps or leaves a gap" % (where, name))
        pos = end
        raw = body[begin:end]
        if dt == "BF16":
            arr = _from_bf16_bytes(raw, count)
        else:
            arr = np.frombuffer(raw, dtype=_DTYPES[dt][0], count=count).astype(np.float32)
        arr = arr.reshape(shape)
        if not np.all(np.isfinite(arr)):
            raise FormatError("%s: tensor %r contains NaN or Inf" % (where, name))
        tensors[name] = arr
    if pos != len(body):
        raise FormatError("%s: %d trailing bytes after the tensor data" % (where, len(body) - pos))
    return tensors, metadata


class InrFile(object):
    """A parsed model file: tensors plus the decoded metadata."""

    def __init__(self, path, tensors, metadata):
        self.path = str(path)
        self.tensors = tensors
        self.metadata = metadata

        def j(key, default=None, required=False):
            if key not in metadata:
                if required:
                    raise FormatError("%s: __metadata__ lacks %r" % (self.path, key))
                return default
            try:
                return json.loads(metadata[key], object_pairs_hook=collections.OrderedDict)
            except ValueError as e:
                raise FormatError("%s: __metadata__[%r] is not valid JSON: %s"
                                  % (self.path, key, e))

        if metadata.get("format") != FORMAT_NAME:
            raise FormatError("%s: __metadata__['format'] must be %r" % (self.path, FORMAT_NAME))
        if metadata.get("format_version") != str(FORMAT_VERSION):
            raise FormatError("%s: format_version %r is not supported (this reader supports %d)"
                              % (self.path, metadata.get("format_version"), FORMAT_VERSION))
        self.architecture = j("architecture", required=True)
        self.domain = j("domain", required=True)
        self.output = j("output")
        self.value_range = j("value_range")
        self.name = metadata.get("name")
        self.description = metadata.get("description")
        self.provenance = metadata.get("provenance")

    def parameter_count(self):
        return int(sum(a.size for a in self.tensors.values()))


def read_inr(path):
    """Read an INR Volume file (the container is always parsed by this module, so the strict
    container checks apply whether or not the safetensors package is installed)."""
    tensors, metadata = read_safetensors(path)
    return InrFile(path, tensors, metadata)
