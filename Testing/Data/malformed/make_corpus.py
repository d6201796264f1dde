#!/usr/bin/env python3
"""Writes the malformed-model corpus: one damaged INR Volume file per failure class the loader
must reject, plus manifest.json (file -> failure class -> a substring the error must contain).

Standard library only, deterministic. Re-run after changing it:
    /usr/bin/python3 Testing/Data/malformed/make_corpus.py
"""
import json
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))

ARCH = {"input_dim": 4, "layers": [
    {"type": "linear", "weight": "l0.weight", "bias": "l0.bias"},
    {"type": "sine", "w0": 30},
    {"type": "linear", "weight": "l1.weight", "bias": "l1.bias"}]}
DOMAIN = {"bounds": [0, 1, 0, 1, 0, 1], "time_range": [0, 1]}


def tensors():
    """A valid tiny SIREN 4->8->1 with deterministic weights."""
    vals = lambda n, s: [((i * 37 + s * 11) % 17 - 8) / 40.0 for i in range(n)]
    return [("l0.weight", "F32", [8, 4], vals(32, 1)), ("l0.bias", "F32", [8], vals(8, 2)),
            ("l1.weight", "F32", [1, 8], vals(8, 3)), ("l1.bias", "F32", [1], vals(1, 4))]


def metadata(arch=ARCH, domain=DOMAIN, **extra):
    m = {"format": "inr-volume", "format_version": "1",
         "architecture": json.dumps(arch), "domain": json.dumps(domain)}
    m.update(extra)
    return m


def pack(dtype, values):
    fmt = {"F32": "f", "F64": "d", "I32": "i", "F16": "e"}[dtype]
    return struct.pack("<%d%s" % (len(values), fmt), *values)


def build(ts=None, meta=None, header_patch=None, data_patch=None):
    ts = tensors() if ts is None else ts
    header, blob = {}, b""
    for name, dtype, shape, values in ts:
        raw = pack(dtype, values)
        header[name] = {"dtype": dtype, "shape": shape, "data_offsets": [len(blob), len(blob) + len(raw)]}
        blob += raw
    header["__metadata__"] = metadata() if meta is None else meta
    if header_patch:
        header_patch(header)
    if data_patch:
        blob = data_patch(blob)
    h = json.dumps(header).encode()
    h += b" " * (-len(h) % 8)
    return struct.pack("<Q", len(h)) + h + blob


def with_header_bytes(raw_header, blob=b""):
    return struct.pack("<Q", len(raw_header)) + raw_header + blob


def replace(ts, name, **kw):
    out = []
    for t in ts:
        if t[0] == name:
            t = (t[0], kw.get("dtype", t[1]), kw.get("shape", t[2]), kw.get("values", t[3]))
        out.append(t)
    return out


CASES = []


def case(cls, fname, expect, data):
    CASES.append({"file": fname, "class": cls, "expect": expect})
    with open(os.path.join(HERE, fname), "wb") as f:
        f.write(data)


def main():
    good = build()
    with open(os.path.join(HERE, "valid_control.inr"), "wb") as f:
        f.write(good)  # the undamaged base: must load, so each failure below is its own
    case("truncated file", "truncated.inr", "too short", good[:5])
    case("header length beyond the file", "header_past_end.inr", "runs past the end",
         struct.pack("<Q", len(good)) + good[8:])
    case("absurd header length", "header_absurd.inr", "absurdly large", struct.pack("<Q", 1 << 62) + good[8:])
    case("malformed JSON", "bad_json.inr", "not valid JSON", with_header_bytes(b'{"l0.weight": {"dtype": "F32",'))
    case("header not an object", "header_not_object.inr", "must be a JSON object", with_header_bytes(b"[1, 2, 3]"))
    case("unsupported dtype", "dtype_int32.inr", "unsupported dtype 'I32'",
         build(replace(tensors(), "l0.bias", dtype="I32", values=[1] * 8)))

    def overlap(h):
        h["l0.bias"]["data_offsets"] = [0, 32]
    case("overlapping tensors", "offsets_overlap.inr", "overlaps", build(header_patch=overlap))

    def out_of_range(h):
        b, e = h["l1.bias"]["data_offsets"]
        h["l1.bias"]["data_offsets"] = [b + 4096, e + 4096]
    case("offsets out of range", "offsets_out_of_range.inr", "run past the end", build(header_patch=out_of_range))
    case("trailing bytes not covered", "offsets_trailing.inr", "trailing bytes",
         build(data_patch=lambda blob: blob + b"\0" * 16))

    def gap(h):
        for name in ("l0.weight", "l0.bias", "l1.weight", "l1.bias"):
            b, e = h[name]["data_offsets"]
            h[name]["data_offsets"] = [b + 8, e + 8]
    case("gap in the data", "offsets_gap.inr", "unaccounted bytes",
         build(header_patch=gap, data_patch=lambda blob: b"\0" * 8 + blob))

    def size_mismatch(h):
        h["l0.bias"]["shape"] = [9]
    case("byte size disagrees with shape", "shape_bytes_mismatch.inr", "needs 36", build(header_patch=size_mismatch))
    case("shape inconsistent with architecture", "shape_mismatch.inr", "expects [8]",
         build([("l0.weight", "F32", [8, 4], tensors()[0][3]), ("l0.bias", "F32", [4], [0.0] * 4),
                ("l1.weight", "F32", [1, 8], tensors()[2][3]), ("l1.bias", "F32", [1], [0.0])]))
    case("wrong input width", "input_width_mismatch.inr", "must be [out, 4]",
         build([("l0.weight", "F32", [8, 3], [0.1] * 24), ("l0.bias", "F32", [8], [0.0] * 8),
                ("l1.weight", "F32", [1, 8], [0.1] * 8), ("l1.bias", "F32", [1], [0.0])]))
    case("missing tensor", "missing_tensor.inr", "not in the file", build(tensors()[:3]))
    case("extra tensor", "extra_tensor.inr", "not used by the architecture",
         build(tensors() + [("stray", "F32", [2], [1.0, 2.0])]))
    case("NaN weight", "nan_weight.inr", "non-finite",
         build(replace(tensors(), "l1.weight", values=[0.1] * 3 + [math.nan] + [0.1] * 4)))
    case("Inf weight", "inf_weight.inr", "non-finite",
         build(replace(tensors(), "l0.bias", values=[math.inf] + [0.0] * 7)))
    arch = json.loads(json.dumps(ARCH))
    arch["layers"][1] = {"type": "gelu"}
    case("unknown layer kind", "unknown_layer.inr", "unknown layer type 'gelu'", build(meta=metadata(arch=arch)))
    arch = json.loads(json.dumps(ARCH))
    arch["layers"][1] = {"type": "sine", "omega": 30}
    case("unknown layer field", "unknown_layer_field.inr", "unknown field 'omega'", build(meta=metadata(arch=arch)))
    arch = json.loads(json.dumps(ARCH))
    arch["layers"] = arch["layers"][:2]
    case("output width not 1", "output_width.inr", "must end at width 1",
         build(tensors()[:2], meta=metadata(arch=arch)))
    case("empty box", "empty_box.inr", "empty box",
         build(meta=metadata(domain={"bounds": [0, 1, 2, 2, 0, 1], "time_range": [0, 1]})))
    case("t0 >= t1", "bad_time_range.inr", "t0 < t1",
         build(meta=metadata(domain={"bounds": [0, 1, 0, 1, 0, 1], "time_range": [5, 5]})))
    case("input order inconsistent", "bad_input_order.inr", "input_order",
         build(meta=metadata(domain={"bounds": [0, 1, 0, 1, 0, 1], "time_range": [0, 1],
                                     "input_order": ["x", "x", "z", "t"]})))
    meta = metadata()
    del meta["architecture"]
    case("missing architecture", "missing_architecture.inr", "'architecture' is missing", build(meta=meta))
    meta = metadata()
    meta["architecture"] = "{layers: oops"
    case("architecture not JSON", "architecture_bad_json.inr", "'architecture' is not valid JSON", build(meta=meta))
    meta = metadata()
    del meta["format"]
    case("not an INR model (plain safetensors)", "plain_safetensors.inr", "not an INR Volume model", build(meta=meta))
    case("unsupported format version", "future_version.inr", "not supported",
         build(meta=metadata(format_version="99")))
    # Numbers that are valid JSON but overflow what the loader and the fp32 renderer can use.
    case("box extent overflows", "bounds_overflow.inr", "domain.bounds: the x extent",
         build(meta=metadata(domain={"bounds": [-1e308, 1e308, 0, 1, 0, 1], "time_range": [0, 1]})))
    case("time range overflows", "time_range_overflow.inr", "domain.time_range",
         build(meta=metadata(domain={"bounds": [0, 1, 0, 1, 0, 1], "time_range": [-1e308, 1e308]})))
    case("input map overflows", "input_map_overflow.inr", "onto the network input",
         build(meta=metadata(domain={"bounds": [0, 1e-300, 0, 1, 0, 1], "time_range": [0, 1]})))
    case("resolution out of range", "resolution_huge.inr", "domain.resolution entries",
         build(meta=metadata(domain={"bounds": [0, 1, 0, 1, 0, 1], "time_range": [0, 1], "centering": "cell",
                                     "resolution": [1e300, 4, 4]})))
    meta = metadata()
    meta["architecture"] = json.dumps(ARCH).replace('"w0": 30', '"w0": 1e999')
    case("number overflows double (JSON library error)", "number_overflow.inr",
         "'architecture' holds a number outside the double range", build(meta=meta))
    arch = json.loads(json.dumps(ARCH))
    arch["layers"][1]["w0"] = 1e300
    case("parameter beyond fp32", "w0_beyond_fp32.inr", "layers[1].w0 is 1e+300, outside the fp32 range",
         build(meta=metadata(arch=arch)))
    arch = json.loads(json.dumps(ARCH))
    arch["input_dim"] = 2 ** 32 + 4
    case("input_dim beyond int", "input_dim_huge.inr", "input_dim is 4294967300", build(meta=metadata(arch=arch)))
    case("field of the wrong JSON type", "centering_not_string.inr", "domain.centering must be a string",
         build(meta=metadata(domain={"bounds": [0, 1, 0, 1, 0, 1], "time_range": [0, 1], "centering": 5})))
    case("output scale beyond fp32", "output_scale_huge.inr", "output.scale is",
         build(meta=metadata(output=json.dumps({"scale": 1e300}))))
    case("per-time output map overflows", "per_time_overflow.inr", "output.per_time: the value map",
         build(meta=metadata(output=json.dumps({"per_time": {"times": [0, 1], "min": [-1e308, 0],
                                                             "max": [1e308, 1]}}))))
    case("value range beyond fp32", "value_range_huge.inr", "value_range",
         build(meta=metadata(value_range=json.dumps([1e300, 2e300]))))
    case("zero-element tensor", "empty_tensor.inr", "has no elements",
         build(tensors() + [("empty", "F32", [0], [])]))
    case("F64 weight beyond fp32", "f64_beyond_fp32.inr", "outside the fp32 range",
         build(replace(tensors(), "l0.bias", dtype="F64", values=[1e300] + [0.0] * 7)))

    # Hash grids (tiny-cuda-nn's HashGrid): 2 levels of 2 features over x, y, z with base
    # resolution 2, per-level scale 2 and 2^4 entries: level 0 dense (2^3 = 8 entries), level 1
    # hashed (4^3 > 16): 24 entries in all.
    def hashgrid(table_rows=24, inputs=3, **fields):
        grid = {"type": "hashgrid", "table": "enc.table", "n_levels": 2, "n_features_per_level": 2,
                "log2_hashmap_size": 4, "base_resolution": 2, "per_level_scale": 2.0}
        grid.update(fields)
        layers = [grid, {"type": "linear", "weight": "out.weight", "bias": None}]
        if inputs != 3:
            layers.insert(0, {"type": "linear", "weight": "in.weight", "bias": None})
        ts = [("enc.table", "F16", [table_rows, 2], [((i * 7) % 5 - 2) / 8.0 for i in range(2 * table_rows)]),
              ("out.weight", "F32", [1, 4], [0.25, -0.5, 0.75, 1.0])]
        if inputs != 3:
            ts.append(("in.weight", "F32", [inputs, 3], [0.1] * (3 * inputs)))
        return build(ts, metadata(arch={"input_dim": 3, "layers": layers}))
    case("valid hash grid (control)", "valid_hashgrid_control.inr", "", hashgrid())
    CASES.pop()  # a control, not a failure class: HashGrid_test loads it
    case("hash-grid table size mismatch", "hashgrid_table_size.inr",
         "architecture.layers[0].table expects [24, 2]", hashgrid(table_rows=20))
    case("hash-grid without levels", "hashgrid_levels_zero.inr", "architecture.layers[0].n_levels is 0",
         hashgrid(n_levels=0))
    case("hash-grid table size out of range", "hashgrid_log2_size.inr",
         "architecture.layers[0].log2_hashmap_size is 31", hashgrid(log2_hashmap_size=31))
    case("hash-grid features per level not a power of 2", "hashgrid_features.inr",
         "n_features_per_level is 3; it must be 1, 2, 4 or 8", hashgrid(n_features_per_level=3))
    case("hash-grid levels getting coarser", "hashgrid_scale_below_1.inr", "per_level_scale is 0.5",
         hashgrid(per_level_scale=0.5))
    case("hash-grid unsupported interpolation", "hashgrid_interpolation.inr",
         'interpolation must be "linear" or "smoothstep", not "Nearest"', hashgrid(interpolation="Nearest"))
    case("hash-grid finest level beyond 2^24", "hashgrid_too_fine.inr", "at most 2^24 is supported",
         hashgrid(base_resolution=65536, per_level_scale=1024.0))
    case("hash grid not on the coordinates", "hashgrid_not_first.inr", "a hash grid encodes 3 coordinates",
         hashgrid(inputs=8))
    case("hash-grid unknown option", "hashgrid_unknown_field.inr", "unknown field 'hash'",
         hashgrid(hash="ReversedPrime"))

    def header_overflow(h):
        h["l0.bias"]["data_offsets"] = "OVERFLOW"
    raw = build(header_patch=header_overflow)
    n = struct.unpack("<Q", raw[:8])[0]
    hdr = raw[8:8 + n].rstrip().replace(b'"OVERFLOW"', b"[32, 1e999]")
    hdr += b" " * (-len(hdr) % 8)
    case("header number overflows double", "header_number_overflow.inr", "number overflow",
         struct.pack("<Q", len(hdr)) + hdr + raw[8 + n:])
    with open(os.path.join(HERE, "manifest.json"), "w") as f:
        json.dump(CASES, f, indent=1)
        f.write("\n")
    print("wrote %d malformed files to %s" % (len(CASES), HERE))


if __name__ == "__main__":
    main()
