"""A plain PyTorch hash-grid network: the module whose state_dict ``inr_export.py hashgrid-torch``
reads, and a second, independent implementation of the encoding for the parity tests.

``HashGridEncoding(dims, **tcnn_encoding_fields)`` follows tiny-cuda-nn's ``HashGrid``
(Docs/FORMAT.md "hashgrid"): inputs in [0, 1]; its state_dict holds

  ``embeddings``  [entries, n_features_per_level]: the flat table, tiny-cuda-nn's layout
  ``offsets``     [n_levels + 1] int64 buffer: each level's first entry (and the total)

``HashGridNetwork(dims, encoding_config, width, hidden_layers, activation, output_activation)``
is the encoding followed by ``network``, an ``nn.Sequential`` of Linear layers with the hidden
activation between them (keys ``network.{i}.weight`` / ``.bias``).
"""

import torch
from torch import nn

import inr_hashgrid

_ACTIVATIONS = {"relu": nn.ReLU, "sigmoid": nn.Sigmoid, "tanh": nn.Tanh, "silu": nn.SiLU}


class HashGridEncoding(nn.Module):
    """``exact_position``: each level's position x * scale + 0.5 rounded once to fp32, as
    tiny-cuda-nn's fmaf (and this project's evaluators) compute it, by way of float64: for
    references. Off, it is rounded twice in fp32 (cheaper on a GPU, for training and timing): an
    ulp apart at times, which at a fine level's scale is a visible fraction of a cell."""

    def __init__(self, dims, exact_position=False, **config):
        super().__init__()
        self.exact_position = bool(exact_position)
        self.spec = inr_hashgrid.HashGridSpec(dims, **config)
        s = self.spec
        self.embeddings = nn.Parameter(torch.empty(s.entries, s.n_features_per_level).uniform_(-1e-4, 1e-4))
        self.register_buffer("offsets", torch.tensor(s.offsets + [s.entries], dtype=torch.int64))
        # The cell's 2^D vertices as offsets from its lower corner (bit d of vertex c: axis d);
        # not part of the state_dict.
        corners = [[(c >> d) & 1 for d in range(s.dims)] for c in range(1 << s.dims)]
        self.register_buffer("corners", torch.tensor(corners, dtype=torch.int64), persistent=False)

    def forward(self, x):
        s = self.spec
        x = x.to(torch.float32)
        features = []
        for level in range(s.n_levels):
            if self.exact_position:  # fp32 x times fp32 scale plus 0.5 is exact in float64
                pos = (x.double() * float(s.scales[level]) + 0.5).float()
            else:
                pos = x * float(s.scales[level]) + 0.5
            cell = torch.floor(pos)
            t = pos - cell
            if s.interpolation == "smoothstep":
                t = t * t * (3 - 2 * t)
            cell = cell.to(torch.int64)
            table = self.embeddings[s.offsets[level]:s.offsets[level] + s.sizes[level]]
            acc = 0
            for up in self.corners:
                vertex = (cell + up) & 0xFFFFFFFF
                weight = torch.prod(torch.where(up.bool(), t, 1 - t), dim=1, keepdim=True)
                acc = acc + weight * table[self._index(level, vertex)]
            features.append(acc)
        return torch.cat(features, dim=1)

    def _index(self, level, v):
        s = self.spec
        res, size = s.resolutions[level], s.sizes[level]
        if res ** s.dims <= size:
            index = torch.zeros_like(v[:, 0])
            stride = 1
            for d in range(s.dims):
                index = (index + v[:, d] * stride) & 0xFFFFFFFF
                stride *= res
        else:
            index = torch.zeros_like(v[:, 0])
            for d in range(s.dims):
                index = index ^ ((v[:, d] * inr_hashgrid.PRIMES[d]) & 0xFFFFFFFF)
        return index % size


class HashGridNetwork(nn.Module):
    def __init__(self, dims, encoding_config, width=64, hidden_layers=2, activation="relu",
                 output_activation=None):
        super().__init__()
        self.encoding = HashGridEncoding(dims, **encoding_config)
        layers, fan_in = [], self.encoding.spec.n_output_dims
        for _ in range(hidden_layers):
            layers += [nn.Linear(fan_in, width), _ACTIVATIONS[activation]()]
            fan_in = width
        layers.append(nn.Linear(fan_in, 1))
        if output_activation:
            layers.append(_ACTIVATIONS[output_activation]())
        self.network = nn.Sequential(*layers)

    def forward(self, x):
        return self.network(self.encoding(x))

    def forward_points(self, x):
        """For inputs in [-1, 1] (Tools/training's coordinates): the grid spans [0, 1]."""
        return self.forward(0.5 * (x + 1.0))[:, 0]
