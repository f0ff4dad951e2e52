#!/usr/bin/env python3
"""Dev-time reference: one training step of each network in PyTorch, the same architectures
as hdrsynth's, as `cargo bench --bench train_step` runs them:
- Network-1 (src/models/blend_unet.rs: base width 32, depth 4, BatchNorm, 256 classes, 5x5
  head), batch 4 of 6x128x128, paper Eq. 4 via 2*(1 - p_target)*alpha, Adam;
- Network-2 (src/models/wu.rs: Wu et al.'s released ResNet, b = 64, 9 residual blocks,
  TensorFlow 'SAME' reflection padding, TensorFlow deconvolution alignment), batch 4 of
  18x256x256, mu-law (mu = 5000) L2, Adam.
The parameter counts printed must equal hdrsynth's (7,968,928 and 16,606,339). Prints the
median step time per network. Never a runtime dependency:
    python3 -m venv /tmp/torchenv && /tmp/torchenv/bin/pip install torch
    /tmp/torchenv/bin/python tools/torch_step_reference.py [--network 1|2|both] [--threads N]
tools/speed_compare.sh runs it beside Burn's bench and prints the ratios.
"""
import argparse
import statistics
import time

import torch
import torch.nn as nn
import torch.nn.functional as F


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


LEAK = 0.2


def same_pad(k, s):
    # TensorFlow 'SAME' total padding for sizes divisible by the stride; the extra pixel after.
    total = max(k - s, 0)
    return (total // 2, total - total // 2)


class ConvSame(nn.Module):
    """ops.conv2d(padding='REFLECT') of the released code: reflection padding sized as 'SAME'."""

    def __init__(self, cin, cout, k, s):
        super().__init__()
        a, b = same_pad(k, s)
        self.pad = nn.ReflectionPad2d((a, b, a, b))
        self.conv = nn.Conv2d(cin, cout, k, stride=s)

    def forward(self, x):
        return self.conv(self.pad(x))


class Wu(nn.Module):
    def __init__(self, b=64, res_blocks=9, hdr_input_scale=0.25):
        super().__init__()
        self.enc1 = nn.ModuleList([ConvSame(6, b, 5, 2) for _ in range(3)])
        self.enc2 = nn.ModuleList([ConvSame(b, 2 * b, 5, 2) for _ in range(3)])
        self.enc_bn = nn.ModuleList([nn.BatchNorm2d(2 * b) for _ in range(3)])
        m = 4 * b
        self.down = ConvSame(6 * b, m, 5, 2)
        self.down_bn = nn.BatchNorm2d(m)
        self.res = nn.ModuleList([nn.ModuleList([ConvSame(m, m, 3, 1), nn.BatchNorm2d(m),
                                                 ConvSame(m, m, 3, 1), nn.BatchNorm2d(m)])
                                  for _ in range(res_blocks)])
        plan = [(2 * m, 2 * b), (2 * b + 6 * b, b), (b + 3 * b, b)]
        # TensorFlow alignment: padding 1, then the extra last row and column cropped.
        self.up = nn.ModuleList([nn.ConvTranspose2d(i, o, 5, stride=2, padding=1) for i, o in plan])
        self.up_bn = nn.ModuleList([nn.BatchNorm2d(o) for _, o in plan])
        self.out = ConvSame(b, 3, 5, 1)
        scale = torch.tensor([2.0 if c % 6 < 3 else 2.0 * hdr_input_scale for c in range(18)])
        self.register_buffer("scale", scale.view(1, 18, 1, 1))

    def forward(self, x):
        x = x * self.scale - 1.0
        e1, e2 = [], []
        for i in range(3):
            a = self.enc1[i](x[:, 6 * i:6 * i + 6])
            e2.append(self.enc_bn[i](self.enc2[i](F.leaky_relu(a, LEAK))))
            e1.append(a)
        e1, e2 = torch.cat(e1, 1), torch.cat(e2, 1)
        deep = self.down_bn(self.down(F.leaky_relu(e2, LEAK)))
        r = deep
        for c1, b1, c2, b2 in self.res:
            h = F.relu(r)
            r = h + b2(c2(F.relu(b1(c1(h)))))
        cur = torch.cat([r, deep], 1)
        for up, bn, skip in zip(self.up, self.up_bn, [e2, e1, None]):
            y = up(F.relu(cur))
            y = bn(y[:, :, :-1, :-1])
            cur = y if skip is None else torch.cat([y, skip], 1)
        return (torch.tanh(self.out(F.relu(cur))) + 1.0) * 0.5


def mu_law(x, mu=5000.0):
    return torch.log1p(mu * x) / torch.log1p(torch.tensor(mu))


def time_steps(model, step, steps):
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    times = []
    for i in range(steps + 2):
        t0 = time.perf_counter()
        loss = step(model)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if i >= 2:
            times.append(time.perf_counter() - t0)
    return times


def report(name, model, times, threads):
    n = sum(p.numel() for p in model.parameters())
    print(f"{name}: torch {torch.__version__}, {threads} threads, {n} trainable parameters: "
          f"median {statistics.median(times):.3f} s per step (min {min(times):.3f}, "
          f"{len(times)} steps)", flush=True)


def network1(threads, steps):
    model = BlendUNet()
    x = torch.rand(4, 6, 128, 128)
    t = torch.randint(0, 256, (4, 128, 128))
    alpha = torch.rand(256) + 0.5

    def step(m):
        p = torch.softmax(m(x), 1)
        pt = p.gather(1, t.unsqueeze(1)).squeeze(1)
        return (2 * (1 - pt) * alpha[t]).mean()

    report("network1/b4/128px", model, time_steps(model, step, steps), threads)


def network2(threads, steps):
    model = Wu()
    x = torch.rand(4, 18, 256, 256)
    y = torch.rand(4, 3, 256, 256)

    def step(m):
        return ((mu_law(m(x)) - mu_law(y)) ** 2).mean()

    report("network2/b4/256px", model, time_steps(model, step, steps), threads)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--network", choices=["1", "2", "both"], default="both")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    if a.network in ("1", "both"):
        network1(a.threads, a.steps)
    if a.network in ("2", "both"):
        network2(a.threads, a.steps)


if __name__ == "__main__":
    main()
