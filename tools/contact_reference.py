#!/usr/bin/env python3
"""Reference fixture for the DGCNN contact network, computed with PyTorch.

Run by hand (never by tests or CI) from the repository root:

    python3 -m venv /tmp/torch && /tmp/torch/bin/pip install torch numpy safetensors
    /tmp/torch/bin/python tools/contact_reference.py

It builds the network of the design notes in PyTorch, literally (one linear map per layer
applied to every edge, h'_i = AGG_j ReLU(theta(h_i - h_j) + phi(h_i))), with tensor names as
the model-file section fixes them, and writes

- fixtures/contact/reference_weights.safetensors: seeded float32 weights (a model file);
- fixtures/contact/reference_io.safetensors: a 2048-point input (float64, two finger-like
  surfaces in metres), the logits for max and sum aggregation in float64 and float32, and the
  kNN table of every layer (int16, nearest first).

The Rust tests (crates/moe-contact/tests/it/reference.rs) load both files and compare.
"""

import pathlib

import numpy as np
import torch
from safetensors.torch import save_file

K = 30
WIDTHS = (64, 128, 256)
HEAD = (512, 256)
SEED = 20260
N_PER_FINGER = 1024


class EdgeConv(torch.nn.Module):
    def __init__(self, width_in, width):
        super().__init__()
        self.theta = torch.nn.Parameter(torch.empty(width, width_in))
        torch.nn.init.kaiming_uniform_(self.theta, a=5 ** 0.5)
        self.phi = torch.nn.Linear(width_in, width)

    def forward(self, h, aggregation):
        idx = knn(h, K)  # (N, k)
        h_j = h[idx]  # (N, k, C)
        h_i = h.unsqueeze(1).expand_as(h_j)
        edges = torch.relu((h_i - h_j) @ self.theta.T + self.phi(h_i))  # per edge, literally
        out = edges.max(dim=1).values if aggregation == "max" else edges.sum(dim=1)
        return out, idx


class Dgcnn(torch.nn.Module):
    def __init__(self, in_channels=3):
        super().__init__()
        w1, w2, w3 = WIDTHS
        self.edge1 = EdgeConv(in_channels, w1)
        self.edge2 = EdgeConv(w1, w2)
        self.edge3 = EdgeConv(w2, w3)
        local = sum(WIDTHS)
        self.head = torch.nn.ModuleList(
            [torch.nn.Linear(2 * local, HEAD[0]), torch.nn.Linear(HEAD[0], HEAD[1]),
             torch.nn.Linear(HEAD[1], 2)])
        self.dropout = torch.nn.Dropout(0.5)

    def forward(self, x, aggregation):
        h1, i1 = self.edge1(x, aggregation)
        h2, i2 = self.edge2(h1, aggregation)
        h3, i3 = self.edge3(h2, aggregation)
        loc = torch.cat([h1, h2, h3], dim=1)
        glob = loc.max(dim=0, keepdim=True).values.expand_as(loc)
        z = torch.cat([loc, glob], dim=1)
        z = self.dropout(torch.relu(self.head[0](z)))
        z = self.dropout(torch.relu(self.head[1](z)))
        return self.head[2](z), (i1, i2, i3)


def knn(h, k):
    """The k points with the smallest squared distance, the point itself first (distance 0),
    ties to the lower index."""
    inner = h @ h.T
    xx = (h * h).sum(dim=1)
    d = (xx[:, None] + xx[None, :]) - 2.0 * inner
    d = d.clamp_min(0.0)
    d.fill_diagonal_(0.0)
    _, order = torch.sort(d, dim=1, stable=True)
    return order[:, :k]


def finger_points(rng, centre_x, facing):
    """Points near the surface of a bent capsule-like finger, metres."""
    t = rng.uniform(0.0, 1.0, N_PER_FINGER)
    angle = rng.uniform(0.0, 2.0 * np.pi, N_PER_FINGER)
    radius = 0.011 - 0.003 * t + rng.normal(0.0, 2e-4, N_PER_FINGER)
    z = 0.08 * t
    bend = 0.01 * t ** 2 * facing
    x = centre_x + bend + radius * np.cos(angle)
    y = radius * np.sin(angle)
    return np.stack([x, y, z], axis=1)


def main():
    root = pathlib.Path(__file__).resolve().parent.parent
    out = root / "fixtures" / "contact"
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(SEED)
    model = Dgcnn().eval()
    weights = {name: t.detach().float().contiguous() for name, t in model.state_dict().items()}
    save_file(weights, str(out / "reference_weights.safetensors"))

    rng = np.random.default_rng(SEED)
    points = np.concatenate([finger_points(rng, -0.03, 1.0), finger_points(rng, 0.03, -1.0)])
    tensors = {"input": torch.from_numpy(points).double().contiguous()}
    with torch.no_grad():
        for dtype, tag in [(torch.float64, "f64"), (torch.float32, "f32")]:
            model = model.to(dtype)
            x = torch.from_numpy(points).to(dtype)
            for aggregation in ["max", "sum"]:
                logits, idx = model(x, aggregation)
                tensors[f"logits_{aggregation}_{tag}"] = logits.double().contiguous()
                for layer, table in enumerate(idx, start=1):
                    if layer == 1 and aggregation == "sum":
                        continue  # the first layer's kNN is on the input: the same for both
                    name = f"knn_{tag}_layer1" if layer == 1 else f"knn_{aggregation}_{tag}_layer{layer}"
                    tensors[name] = table.to(torch.int16).contiguous()
    save_file(tensors, str(out / "reference_io.safetensors"))
    for name in sorted(tensors):
        print(name, tuple(tensors[name].shape), tensors[name].dtype)


if __name__ == "__main__":
    main()
