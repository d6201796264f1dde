"""PyTorch modules that reproduce the state_dict layouts and forward semantics of the public
INR implementations that ``inr_export.py`` converts. Written for this project (no code taken
from those repositories); they exist so tests and ``train_test_models.py`` can build models
in exactly the official layouts.

=================  ==========================================  ============================
layout             state_dict keys                             official source
=================  ==========================================  ============================
siren-notebook     net.{i}.linear.weight/bias, last            vsitzmann/siren
                   net.{k}.weight/bias (outermost linear)      explore_siren.ipynb ``Siren``
siren-modules      net.net.{i}.0.weight/bias                   vsitzmann/siren modules.py
                                                               ``SingleBVPNet``/``FCBlock``
coordnet           net.{i}.net.{0,1}.linear.*,                 stevenhan1991/TVCG23-CoordNet
                   net.{i}.transform.linear.* (width change)   Code/model.py ``CoordNet``
neurcomp           net_layers.0.linear.*,                      matthewberger/neurcomp
                   net_layers.{i}.linear_{1,2}.*,              siren.py ``FieldNet``
                   net_layers.{k}.weight/bias
reed-ffn           main.{0,2,4,6}.weight [o,i,1,1,1]/bias      awreed/DynamicCTReconstruction
                   (B is not in the state_dict)                nn_models.py ``INR_3D``
=================  ==========================================  ============================

All modules take network inputs of shape (N, in) and return (N,) (``forward_points``).
"""

import math

import torch
from torch import nn


class _Sine(nn.Module):
    def __init__(self, w0=30.0):
        super().__init__()
        self.w0 = w0

    def forward(self, x):
        return torch.sin(self.w0 * x)


class _Swish(nn.Module):
    def forward(self, x):
        return x * torch.sigmoid(x)


class _SineLinear(nn.Module):
    """A linear layer stored as ``.linear`` followed by sin(w0 * .)."""

    def __init__(self, fan_in, fan_out, w0=30.0, first=False):
        super().__init__()
        self.w0 = w0
        self.linear = nn.Linear(fan_in, fan_out)
        with torch.no_grad():  # SIREN initialisation
            r = 1.0 / fan_in if first else math.sqrt(6.0 / fan_in) / w0
            self.linear.weight.uniform_(-r, r)

    def forward(self, x):
        return torch.sin(self.w0 * self.linear(x))


def _siren_final(fan_in, fan_out, w0=30.0):
    lin = nn.Linear(fan_in, fan_out)
    with torch.no_grad():
        r = math.sqrt(6.0 / fan_in) / w0
        lin.weight.uniform_(-r, r)
    return lin


class SirenNotebook(nn.Module):
    """explore_siren.ipynb layout: net = Sequential(SineLayer..., [Linear | SineLayer])."""

    def __init__(self, in_features, hidden_features, hidden_layers, out_features=1,
                 outermost_linear=True, first_omega_0=30.0, hidden_omega_0=30.0):
        super().__init__()
        mods = [_SineLinear(in_features, hidden_features, first_omega_0, first=True)]
        for _ in range(hidden_layers):
            mods.append(_SineLinear(hidden_features, hidden_features, hidden_omega_0))
        if outermost_linear:
            mods.append(_siren_final(hidden_features, out_features, hidden_omega_0))
        else:
            mods.append(_SineLinear(hidden_features, out_features, hidden_omega_0))
        self.net = nn.Sequential(*mods)

    def forward_points(self, x):
        return self.net(x)[:, 0]


class _FCBlock(nn.Module):
    """modules.py FCBlock layout: net = Sequential(Sequential(Linear, nl), ..., Sequential(Linear))."""

    def __init__(self, in_features, out_features, num_hidden_layers, hidden_features,
                 outermost_linear=True, nonlinearity="sine"):
        super().__init__()

        def nl():
            return {"sine": lambda: _Sine(30.0), "relu": nn.ReLU, "tanh": nn.Tanh,
                    "sigmoid": nn.Sigmoid}[nonlinearity]()

        widths = [in_features] + [hidden_features] * (num_hidden_layers + 1)
        blocks = []
        for i in range(len(widths) - 1):
            lin = nn.Linear(widths[i], widths[i + 1])
            if nonlinearity == "sine":
                with torch.no_grad():
                    r = 1.0 / widths[i] if i == 0 else math.sqrt(6.0 / widths[i]) / 30.0
                    lin.weight.uniform_(-r, r)
            blocks.append(nn.Sequential(lin, nl()))
        last = nn.Linear(hidden_features, out_features)
        if nonlinearity == "sine":
            with torch.no_grad():
                r = math.sqrt(6.0 / hidden_features) / 30.0
                last.weight.uniform_(-r, r)
        blocks.append(nn.Sequential(last) if outermost_linear else nn.Sequential(last, nl()))
        self.net = nn.Sequential(*blocks)

    def forward(self, x):
        return self.net(x)


class SirenModules(nn.Module):
    """modules.py SingleBVPNet layout (mode 'mlp'): keys net.net.{i}.0.weight/bias."""

    def __init__(self, in_features, hidden_features, num_hidden_layers, out_features=1,
                 nonlinearity="sine"):
        super().__init__()
        self.net = _FCBlock(in_features, out_features, num_hidden_layers, hidden_features,
                            outermost_linear=True, nonlinearity=nonlinearity)

    def forward_points(self, x):
        return self.net(x)[:, 0]


class _CoordNetResBlock(nn.Module):
    def __init__(self, fan_in, fan_out):
        super().__init__()
        self.net = nn.Sequential(_SineLinear(fan_in, fan_out), _SineLinear(fan_out, fan_out))
        self.flag = fan_in != fan_out
        if self.flag:
            self.transform = _SineLinear(fan_in, fan_out)

    def forward(self, x):
        y = self.net(x)
        if self.flag:
            x = self.transform(x)
        return 0.5 * (y + x)


class CoordNet(nn.Module):
    """Code/model.py CoordNet layout: net.{i} = ResBlock(net.{0,1} SineLayers, transform).
    Inputs are (t, z, y, x) in [-1, 1]; the target is normalised per time step to [-1, 1]."""

    def __init__(self, in_features=4, out_features=1, init_features=64, num_res=10):
        super().__init__()
        f = init_features
        blocks = [_CoordNetResBlock(in_features, f), _CoordNetResBlock(f, 2 * f),
                  _CoordNetResBlock(2 * f, 4 * f)]
        blocks += [_CoordNetResBlock(4 * f, 4 * f) for _ in range(num_res)]
        blocks.append(_CoordNetResBlock(4 * f, out_features))
        self.net = nn.Sequential(*blocks)

    def forward_points(self, x):
        return self.net(x)[:, 0]


class _PlainLinear(nn.Module):
    """CoordNet's LinearLayer: a Linear stored as ``.linear``."""

    def __init__(self, fan_in, fan_out):
        super().__init__()
        self.linear = nn.Linear(fan_in, fan_out)
        with torch.no_grad():
            self.linear.weight.uniform_(-1.0 / fan_in, 1.0 / fan_in)

    def forward(self, x):
        return self.linear(x)


class _CoordNetReLUBlock(nn.Module):
    def __init__(self, fan_in, fan_out):
        super().__init__()
        self.net = nn.Sequential(_PlainLinear(fan_in, fan_out), nn.ReLU(),
                                 _SineLinear(fan_out, fan_out), nn.ReLU())
        self.flag = fan_in != fan_out
        if self.flag:
            self.transform = nn.Sequential(_PlainLinear(fan_in, fan_out), nn.ReLU())

    def forward(self, x):
        y = self.net(x)
        if self.flag:
            x = self.transform(x)
        return 0.5 * (y + x)


class CoordNetReLU(nn.Module):
    """Code/model.py CoordNetReLU layout."""

    def __init__(self, in_features=4, out_features=1, init_features=64, num_res=10):
        super().__init__()
        f = init_features
        blocks = [_CoordNetReLUBlock(in_features, f), _CoordNetReLUBlock(f, 2 * f),
                  _CoordNetReLUBlock(2 * f, 4 * f)]
        blocks += [_CoordNetReLUBlock(4 * f, 4 * f) for _ in range(num_res)]
        blocks += [_CoordNetReLUBlock(4 * f, 2 * f), _PlainLinear(2 * f, out_features),
                   nn.Tanh()]
        self.net = nn.Sequential(*blocks)

    def forward_points(self, x):
        return self.net(x)[:, 0]


class _ResidualSine(nn.Module):
    """neurcomp ResidualSineLayer: w2 * (x + sin(30 L2(sin(30 L1(w1 x)))))."""

    def __init__(self, features, ave_first, ave_second, w0=30.0):
        super().__init__()
        self.w0 = w0
        self.linear_1 = nn.Linear(features, features)
        self.linear_2 = nn.Linear(features, features)
        self.weight_1 = 0.5 if ave_first else 1.0
        self.weight_2 = 0.5 if ave_second else 1.0
        with torch.no_grad():
            r = math.sqrt(6.0 / features) / w0
            self.linear_1.weight.uniform_(-r, r)
            self.linear_2.weight.uniform_(-r, r)

    def forward(self, x):
        s1 = torch.sin(self.w0 * self.linear_1(self.weight_1 * x))
        s2 = torch.sin(self.w0 * self.linear_2(s1))
        return self.weight_2 * (x + s2)


class NeurcompFieldNet(nn.Module):
    """neurcomp siren.py FieldNet layout (net_layers ModuleList)."""

    def __init__(self, d_in, layers, d_out=1, is_residual=True):
        super().__init__()
        widths = [d_in] + list(layers) + [d_out]
        n = len(widths) - 1
        self.net_layers = nn.ModuleList()
        for i in range(n):
            if i == n - 1:
                self.net_layers.append(_siren_final(widths[i], widths[i + 1], 30.0))
            elif i == 0 or not is_residual:
                self.net_layers.append(_SineLinear(widths[i], widths[i + 1], first=(i == 0)))
            else:
                if widths[i] != widths[i + 1]:
                    raise ValueError("neurcomp residual layers need equal widths")
                self.net_layers.append(_ResidualSine(widths[i], ave_first=i > 1,
                                                     ave_second=i == n - 2))

    def forward_points(self, x):
        for m in self.net_layers:
            x = m(x)
        return x[:, 0]


def reed_fourier_matrix(num_input_channels, num_features, sigma, seed=0):
    """B exactly as DynamicCTReconstruction's FourierFeatures builds it: the global CPU
    generator is seeded, then B = randn((channels, features), float32) * sigma."""
    torch.manual_seed(seed)
    return torch.randn((num_input_channels, num_features), dtype=torch.float32) * sigma


class ReedFFN(nn.Module):
    """DynamicCTReconstruction INR_3D layout (main.{0,2,4,6} 1x1x1 Conv3d, Swish, Sigmoid)
    together with its Fourier features [sin(2 pi x B), cos(2 pi x B)]. B is a plain attribute
    (not in the state_dict), as in the official code. ``hidden_convs`` = number of hidden
    (2nf -> 2nf) convolutions; the official network has 3."""

    def __init__(self, num_input_channels=3, nf=128, sigma=1.5, seed=0, hidden_convs=3):
        super().__init__()
        self.B = reed_fourier_matrix(num_input_channels, nf, sigma, seed)
        mods = []
        for _ in range(hidden_convs):
            mods += [nn.Conv3d(2 * nf, 2 * nf, kernel_size=1, padding=0), _Swish()]
        mods += [nn.Conv3d(2 * nf, 1, kernel_size=1, padding=0), nn.Sigmoid()]
        self.main = nn.Sequential(*mods)

    def forward_points(self, x):
        p = 2.0 * math.pi * (x @ self.B.to(x.dtype))
        f = torch.cat([torch.sin(p), torch.cos(p)], dim=1)
        return self.main(f[:, :, None, None, None])[:, 0, 0, 0, 0]
