#!/usr/bin/env python3
"""Dev-time reference: one Network-1 training step in PyTorch, the same architecture as
src/models/blend_unet.rs (base width 32, depth 4, BatchNorm, 256 classes, 5x5 head), batch 4,
6x128x128, paper Eq. 4 via 2*(1 - p_target)*alpha, Adam. Prints the median step time.
Never a runtime dependency:  python3 -m venv /tmp/torchenv && /tmp/torchenv/bin/pip install torch
    /tmp/torchenv/bin/python tools/torch_step_reference.py [--threads N] [--steps N]
"""
import argparse
import statistics
import time

import torch
import torch.nn as nn


def block(cin, cout):
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(),
        nn.Conv2d(cout, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout), nn.ReLU())


class BlendUNet(nn.Module):
    def __init__(self, base=32, depth=4, classes=256):
        super().__init__()
        w = [base << l for l in range(depth + 1)]
        self.enc = nn.ModuleList([block(6, w[0])] + [block(w[l - 1], w[l]) for l in range(1, depth + 1)])
        self.up = nn.ModuleList([nn.ConvTranspose2d(w[l + 1], w[l], 2, stride=2) for l in range(depth)])
        self.dec = nn.ModuleList([block(2 * w[l], w[l]) for l in range(depth)])
        self.head = nn.Conv2d(w[0], classes, 5, padding=2)
        self.pool = nn.MaxPool2d(2)

    def forward(self, x):
        skips = []
        x = self.enc[0](x)
        for e in self.enc[1:]:
            skips.append(x)
            x = e(self.pool(x))
        for l in reversed(range(len(self.up))):
            x = self.dec[l](torch.cat([skips.pop(), self.up[l](x)], 1))
        return self.head(x)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=10)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    model = BlendUNet()
    n = sum(p.numel() for p in model.parameters())
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    x = torch.rand(4, 6, 128, 128)
    t = torch.randint(0, 256, (4, 128, 128))
    alpha = torch.rand(256) + 0.5
    times = []
    for i in range(a.steps + 2):
        t0 = time.perf_counter()
        p = torch.softmax(model(x), 1)
        pt = p.gather(1, t.unsqueeze(1)).squeeze(1)
        loss = (2 * (1 - pt) * alpha[t]).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if i >= 2:
            times.append(time.perf_counter() - t0)
    print(f"torch {torch.__version__}, {a.threads} threads, {n} trainable parameters: "
          f"median {statistics.median(times):.3f} s per step (min {min(times):.3f}, "
          f"{len(times)} steps)")


if __name__ == "__main__":
    main()
