"""The multiresolution hash encoding (Mueller et al. 2022; tiny-cuda-nn's ``HashGrid``) in numpy:
the level sizes of the flat table and the encoding itself, as Docs/FORMAT.md ("hashgrid")
defines them. Used by the reference evaluator (inr_reference.py) and the exporter
(inr_export.py); the PyTorch module in inr_hashgrid_torch.py is a separate implementation the
tests compare against.

Conventions (tiny-cuda-nn's): inputs in [0, 1]; level l has scale
``2^(l log2(per_level_scale)) * base_resolution - 1`` (fp32) and resolution ``ceil(scale) + 1``;
its table holds ``min(2^log2_hashmap_size, next_multiple(resolution^D, 8))`` entries of
``n_features_per_level`` features (dense, x fastest, where resolution^D fits; else hashed with
instant-ngp's primes), levels one after the other.
"""

import numpy as np

PRIMES = (1, 2654435761, 805459861, 3674653429)
MAX_LEVELS = 32
MAX_LOG2_HASHMAP_SIZE = 24
MAX_BASE_RESOLUTION = 1 << 16
MAX_FINEST_SCALE = float(1 << 24)
_MAX_DENSE = 2 ** 31 - 1
_U32 = 0xFFFFFFFF


class HashGridSpec(object):
    """The parameters of one hash grid over ``dims`` inputs, with its derived levels."""

    FIELDS = ("n_levels", "n_features_per_level", "log2_hashmap_size", "base_resolution",
              "per_level_scale", "interpolation")

    def __init__(self, dims, n_levels=16, n_features_per_level=2, log2_hashmap_size=19,
                 base_resolution=16, per_level_scale=2.0, interpolation="linear"):
        self.dims = int(dims)
        self.n_levels = int(n_levels)
        self.n_features_per_level = int(n_features_per_level)
        self.log2_hashmap_size = int(log2_hashmap_size)
        self.base_resolution = int(base_resolution)
        self.per_level_scale = float(per_level_scale)
        self.interpolation = str(interpolation).lower()
        problems = []
        if self.dims not in (3, 4):
            problems.append("a hash grid encodes 3 or 4 inputs, not %d" % self.dims)
        if not 1 <= self.n_levels <= MAX_LEVELS:
            problems.append("n_levels is %d; it must be in [1, %d]" % (self.n_levels, MAX_LEVELS))
        if self.n_features_per_level not in (1, 2, 4, 8):
            problems.append("n_features_per_level is %d; it must be 1, 2, 4 or 8"
                            % self.n_features_per_level)
        if not 1 <= self.log2_hashmap_size <= MAX_LOG2_HASHMAP_SIZE:
            problems.append("log2_hashmap_size is %d; it must be in [1, %d]"
                            % (self.log2_hashmap_size, MAX_LOG2_HASHMAP_SIZE))
        if not 1 <= self.base_resolution <= MAX_BASE_RESOLUTION:
            problems.append("base_resolution is %d; it must be in [1, %d]"
                            % (self.base_resolution, MAX_BASE_RESOLUTION))
        if not self.per_level_scale >= 1.0:
            problems.append("per_level_scale is %g; it must be at least 1" % self.per_level_scale)
        if self.interpolation not in ("linear", "smoothstep"):
            problems.append('interpolation must be "linear" or "smoothstep", not %r'
                            % interpolation)
        if problems:
            raise ValueError("; ".join(problems))
        # log2 and exp2 correctly rounded to fp32 (evaluated in float64, then rounded), as the C++
        # loader's std::log2 / std::exp2 of floats give them: numpy's own float32 exp2 is an ulp
        # off at times, which at a fine level's scale moves positions by a visible fraction of a
        # cell.
        log2_scale = np.float32(np.log2(np.float64(np.float32(self.per_level_scale))))
        self.scales, self.resolutions, self.offsets, self.sizes = [], [], [], []
        offset = 0
        for level in range(self.n_levels):
            scale = np.float32(np.float32(np.exp2(np.float64(np.float32(level) * log2_scale)))
                               * np.float32(self.base_resolution) - np.float32(1.0))
            if not scale <= MAX_FINEST_SCALE:
                raise ValueError("level %d has scale %g; at most 2^24 is supported: lower "
                                 "n_levels or per_level_scale" % (level, scale))
            res = int(np.ceil(scale)) + 1
            dense = min(float(res) ** self.dims, _MAX_DENSE)
            size = min((int(dense) + 7) // 8 * 8, 1 << self.log2_hashmap_size)
            self.scales.append(scale)
            self.resolutions.append(res)
            self.offsets.append(offset)
            self.sizes.append(size)
            offset += size
        self.entries = offset

    @classmethod
    def from_json(cls, dims, d, where="hash grid"):
        """From a tiny-cuda-nn style encoding dict (or this format's layer fields)."""
        try:
            return cls(dims, **{k: d[k] for k in cls.FIELDS if k in d})
        except (TypeError, ValueError) as e:
            raise ValueError("%s: %s" % (where, e))

    def to_layer(self, table_name, include_input="none"):
        """The format's layer object."""
        return {"type": "hashgrid", "table": table_name, "n_levels": self.n_levels,
                "n_features_per_level": self.n_features_per_level,
                "log2_hashmap_size": self.log2_hashmap_size,
                "base_resolution": self.base_resolution, "per_level_scale": self.per_level_scale,
                "interpolation": self.interpolation, "include_input": include_input}

    @property
    def table_shape(self):
        return (self.entries, self.n_features_per_level)

    @property
    def n_output_dims(self):
        return self.n_levels * self.n_features_per_level


def vertex_index(spec, level, vertices):
    """Table rows (within the level) of integer vertices [N, D] (uint32 values)."""
    res, size = spec.resolutions[level], spec.sizes[level]
    v = vertices.astype(np.uint64) & _U32
    if res ** spec.dims <= size:  # dense: the grid fits the level
        index = np.zeros(v.shape[0], np.uint64)
        stride = 1
        for d in range(spec.dims):
            index = (index + v[:, d] * np.uint64(stride)) & np.uint64(_U32)
            stride *= res
    else:
        index = np.zeros(v.shape[0], np.uint64)
        for d in range(spec.dims):
            index ^= (v[:, d] * np.uint64(PRIMES[d])) & np.uint64(_U32)
    return index % np.uint64(size)


def encode(spec, table, x):
    """The encoding of inputs x [N, D] (network coordinates, [0, 1] inside the grid) with table
    [entries, F]: [N, n_levels * F] in float64, level-major."""
    x32 = np.asarray(x, np.float32)
    table = np.asarray(table, np.float64)
    F = spec.n_features_per_level
    out = np.zeros((x32.shape[0], spec.n_output_dims))
    for level in range(spec.n_levels):
        # x * scale + 0.5 rounded once to fp32 (tiny-cuda-nn's fmaf)
        pos = (x32.astype(np.float64) * np.float64(spec.scales[level]) + 0.5).astype(np.float32)
        cell = np.floor(pos)
        t = (pos - cell).astype(np.float64)
        if spec.interpolation == "smoothstep":
            t = t * t * (3.0 - 2.0 * t)
        cell = cell.astype(np.int64)
        rows = table[spec.offsets[level]:spec.offsets[level] + spec.sizes[level]]
        acc = np.zeros((x32.shape[0], F))
        for corner in range(1 << spec.dims):
            up = np.array([(corner >> d) & 1 for d in range(spec.dims)])
            weight = np.prod(np.where(up, t, 1.0 - t), axis=1)
            acc += weight[:, None] * rows[vertex_index(spec, level, cell + up).astype(np.int64)]
        out[:, level * F:(level + 1) * F] = acc
    return out
