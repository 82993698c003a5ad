#!/usr/bin/env python3
"""PyTorch's rate for one training step of the paper's DGCNN, to set beside the Rust bench
`cargo bench -p moe-contact --bench bench_main -- train_step` measured the same day.

Run by hand (never by tests or CI) from the repository root:

    python3 -m venv /tmp/torch && /tmp/torch/bin/pip install torch numpy
    /tmp/torch/bin/python tools/torch_train_step.py [--steps 10] [--threads 2]

The network is the paper's (k = 30, EdgeConv 64/128/256 with max aggregation, head 512/256/2
on the per-point features beside their max over the set, dropout 0.5), in PyTorch with the kNN
(top-k of the pairwise distances) outside the autograd graph and, by default, each EdgeConv in
its factored form: max_j ReLU(W[h_j - h_i, h_i] + b) = ReLU(A_i - min_j B_j) with two
per-point products A and B, the neighbours' rows of B gathered and their minimum taken
and head.0's global half computed once per set, as the Rust network does (`--form literal`: the
edge features [h_j - h_i, h_i] gathered for every edge and mapped by the linear layer, then the
max, and head.0 on the global half repeated at every point, as DGCNN's reference code does). One step is what the bench's step is: forward with dropout, weighted
cross-entropy, backward, AdamW (lr 1e-3, weight decay 1e-4), on a batch of 4 frames of the
two-finger hand, either as 4 whole-hand sets of 2048 points (xyz) or as 8 per-finger sets of
1024 points (xyz and rest-pose xyz). Points are two bent finger-like surfaces (as in
tools/contact_reference.py) with about one point in 97 labelled contact. Prints the median
step time and frames per second of each layout.
"""

import argparse
import statistics
import time

import numpy as np
import torch

K = 30
WIDTHS = (64, 128, 256)
HEAD = (512, 256)


def knn(h, k):
    """(B, N, C) -> (B, N, k) indices of the k nearest points by squared distance."""
    inner = h @ h.transpose(1, 2)
    xx = (h * h).sum(dim=2)
    d = xx[:, :, None] + xx[:, None, :] - 2.0 * inner
    return d.topk(k, dim=2, largest=False).indices


class EdgeConv(torch.nn.Module):
    def __init__(self, width_in, width, form):
        super().__init__()
        self.lin = torch.nn.Linear(2 * width_in, width)
        self.form = form

    def forward(self, h):
        b, n, c = h.shape
        with torch.no_grad():
            idx = knn(h, K)  # (B, N, k), outside the autograd graph
        flat = (idx + torch.arange(b)[:, None, None] * n).reshape(-1)
        if self.form == "literal":
            h_j = h.reshape(b * n, c)[flat].reshape(b, n, K, c)
            h_i = h[:, :, None, :].expand(b, n, K, c)
            edges = torch.relu(self.lin(torch.cat([h_j - h_i, h_i], dim=3)))  # (B, N, k, C')
            return edges.max(dim=2).values
        # lin([h_j - h_i, h_i]) = h_i (W2 - W1)^T + bias + h_j W1^T, W = [W1 | W2]: two
        # per-point products, the neighbours' gathered, the max over edges a min over them.
        w1, w2 = self.lin.weight[:, :c], self.lin.weight[:, c:]
        a = h @ (w2 - w1).T + self.lin.bias
        bj = (h @ w1.T).reshape(b * n, -1)[flat].reshape(b, n, K, -1)
        return torch.relu(a - bj.min(dim=2).values)


class Dgcnn(torch.nn.Module):
    def __init__(self, in_channels, form):
        super().__init__()
        self.form = form
        w1, w2, w3 = WIDTHS
        self.edges = torch.nn.ModuleList(
            [EdgeConv(in_channels, w1, form), EdgeConv(w1, w2, form), EdgeConv(w2, w3, form)])
        local = sum(WIDTHS)
        self.head = torch.nn.ModuleList(
            [torch.nn.Linear(2 * local, HEAD[0]), torch.nn.Linear(HEAD[0], HEAD[1]),
             torch.nn.Linear(HEAD[1], 2)])
        self.dropout = torch.nn.Dropout(0.5)

    def forward(self, x):
        feats = []
        h = x
        for layer in self.edges:
            h = layer(h)
            feats.append(h)
        loc = torch.cat(feats, dim=2)
        glob = loc.max(dim=1, keepdim=True).values  # (B, 1, 448)
        if self.form == "literal":
            z = self.head[0](torch.cat([loc, glob.expand_as(loc)], dim=2))
        else:
            # head.0 on [loc | glob] as two products, the global one once per set.
            w = self.head[0].weight
            width = loc.shape[2]
            z = loc @ w[:, :width].T + (glob @ w[:, width:].T + self.head[0].bias)
        z = self.dropout(torch.relu(z))
        z = self.dropout(torch.relu(self.head[1](z)))
        return self.head[2](z)


def finger_points(rng, n, centre_x, facing):
    """Points near the surface of a bent capsule-like finger, metres."""
    t = rng.uniform(0.0, 1.0, n)
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    radius = 0.011 - 0.003 * t + rng.normal(0.0, 2e-4, n)
    bend = 0.01 * t ** 2 * facing
    x = centre_x + bend + radius * np.cos(angle)
    y = radius * np.sin(angle)
    return np.stack([x, y, 0.08 * t], axis=1)


def batch(layout, rng):
    """Inputs (B, N, C) and labels (B, N) of 4 frames in the given layout."""
    fingers = [finger_points(rng, 1024, -0.03, 1.0), finger_points(rng, 1024, 0.03, -1.0)]
    if layout == "whole-hand":
        sets = [np.concatenate(fingers)] * 4
    else:
        sets = [np.concatenate([f, f], axis=1) for f in fingers] * 4
    x = torch.tensor(np.stack(sets), dtype=torch.float32)
    n = x.shape[1]
    y = (torch.arange(n) % 97 == 0).long().expand(x.shape[0], n).contiguous()
    return x, y


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=10, help="timed steps per layout (>= 1)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--form", choices=["factored", "literal"], default="factored",
                        help="EdgeConv as two per-point products and a gathered min and "
                        "head.0's global half once per set (factored), or a linear map of "
                        "every gathered edge and the global half at every point (literal)")
    args = parser.parse_args()
    if args.steps < 1:
        parser.error("--steps must be at least 1")
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, {args.form} form")
    for layout in ["per-finger", "whole-hand"]:
        x, y = batch(layout, rng)
        model = Dgcnn(x.shape[2], args.form).train()
        opt = torch.optim.AdamW(model.parameters(), lr=1e-3, weight_decay=1e-4)
        weight = torch.tensor([1.0, 10.0])
        times = []
        for step in range(args.steps + 2):
            t0 = time.perf_counter()
            opt.zero_grad()
            logits = model(x)
            loss = torch.nn.functional.cross_entropy(
                logits.reshape(-1, 2), y.reshape(-1), weight=weight)
            loss.backward()
            opt.step()
            if step >= 2:  # the first steps warm the allocator and the kernels
                times.append(time.perf_counter() - t0)
        median = statistics.median(times)
        print(f"{layout}: {x.shape[0]} sets of {x.shape[1]} points, median step "
              f"{median * 1e3:.0f} ms over {len(times)} steps, {4 / median:.2f} frames/s")


if __name__ == "__main__":
    main()
