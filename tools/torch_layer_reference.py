#!/usr/bin/env python3
"""Dev-time reference: PyTorch CPU's time per convolution layer of the two networks, to set
beside `cargo bench --bench train_ops` (whose forward + input grad + weight grad columns add up to
this script's forward + backward). Same shapes as the bench: batch 4; Network-2's 5x5 stride-2
layers with the bench's padding, its 3x3 residual conv and 5x5 output layer; Network-1's head.
Prints the median of 5 after one warm-up, per layer: forward alone (no grad) and forward +
backward (dL/dx and dL/dW). Never a runtime dependency:
    /tmp/torchenv/bin/python tools/torch_layer_reference.py [--threads 2]
"""
import argparse
import statistics
import time

import torch

# (name, c_in, c_out, kernel, input size, stride, transposed, padding)
LAYERS = [
    ("Network-2 residual 3x3", 256, 256, 3, 32, 1, False, 1),
    ("Network-2 encoder conv1 5x5 s2", 6, 64, 5, 256, 2, False, 2),
    ("Network-2 encoder conv2 5x5 s2", 64, 128, 5, 128, 2, False, 2),
    ("Network-2 merger down 5x5 s2", 384, 256, 5, 64, 2, False, 2),
    ("Network-2 deconv1 5x5 s2", 512, 128, 5, 32, 2, True, 2),
    ("Network-2 deconv2 5x5 s2", 512, 64, 5, 64, 2, True, 2),
    ("Network-2 deconv3 5x5 s2", 256, 64, 5, 128, 2, True, 2),
    ("Network-2 output 5x5", 64, 3, 5, 256, 1, False, 2),
    ("Network-1 head 5x5", 32, 256, 5, 128, 1, False, 2),
]


def median_time(f, reps=5):
    f()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    print(f"torch {torch.__version__}, {a.threads} threads, batch 4, median of 5 (seconds)")
    print("| layer | forward | forward + backward |")
    print("|---|---|---|")
    for name, cin, cout, k, size, stride, transposed, pad in LAYERS:
        x = torch.rand(4, cin, size, size, requires_grad=True)
        if transposed:
            # Output twice the input, as the bench's padding 2 and output padding 1.
            conv = torch.nn.ConvTranspose2d(cin, cout, k, stride=2, padding=pad, output_padding=1)
        else:
            conv = torch.nn.Conv2d(cin, cout, k, stride=stride, padding=pad)

        def forward():
            with torch.no_grad():
                conv(x)

        def both():
            conv(x).sum().backward()

        print(f"| {name} | {median_time(forward):.4f} | {median_time(both):.4f} |", flush=True)


if __name__ == "__main__":
    main()
