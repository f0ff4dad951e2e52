#!/usr/bin/env bash
# One command, one machine, one run — the training step of both networks in
# Burn (cargo bench --bench train_step, criterion's median) against PyTorch CPU
# (tools/torch_step_reference.py, same architectures, batch, crop, loss, Adam; run before and
# after Burn so drift shows), then whole-image inference in Burn flex against ONNX Runtime
# (cargo bench --features onnx --bench onnx). Prints the ratios; paste them into BENCHMARKS.md
# with the machine and its load.
# TCH_PY=<python of a venv with torch 2.9.0, the libtorch tch 0.22 expects> adds Burn's
# LibTorch backend (`--features tch`, docs/training.md) as a third column.
# ONNX=0 skips the inference half.
#   TORCH_PY=/tmp/torchenv/bin/python THREADS=2 bash tools/speed_compare.sh
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${TORCH_PY:-/tmp/torchenv/bin/python}
THREADS=${THREADS:-2}
log=$(mktemp -d)
echo "machine: $(nproc) cores, $(uname -m); load before: $(cut -d' ' -f1-3 /proc/loadavg)"
"$PY" tools/torch_step_reference.py --threads "$THREADS" | tee "$log/torch1"
RAYON_NUM_THREADS=$THREADS cargo bench --bench train_step 2>&1 | grep -E "s/step|time:" | tee "$log/burn"
if [ -n "${TCH_PY:-}" ]; then
  # LibTorch's intra-op threads follow OMP_NUM_THREADS / torch's default; pin them like PyTorch's.
  TORCH_LIB=$("$TCH_PY" -c 'import os, torch; print(os.path.join(os.path.dirname(torch.__file__), "lib"))')
  PATH="$(dirname "$TCH_PY"):$PATH" LIBTORCH_USE_PYTORCH=1 OMP_NUM_THREADS=$THREADS \
    LD_LIBRARY_PATH="$TORCH_LIB${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
    HDRSYNTH_BENCH_BACKEND=tch cargo bench --features tch --bench train_step 2>&1 \
    | grep -E "s/step|time:" | tee "$log/tch"
fi
"$PY" tools/torch_step_reference.py --threads "$THREADS" | tee "$log/torch2"
if [ "${ONNX:-1}" != 0 ]; then
  ORT_DYLIB_PATH="$(tools/setup_ort.sh)" RAYON_NUM_THREADS=$THREADS \
    cargo bench --features onnx --bench onnx 2>/dev/null | tee "$log/onnx"
fi
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
"$PY" - "$log" <<'PY'
import json, re, sys, pathlib
log = pathlib.Path(sys.argv[1])
torch = {}
for f in ("torch1", "torch2"):
    for line in (log / f).read_text().splitlines():
        m = re.match(r"(\S+): .*median ([0-9.]+) s per step", line)
        if m:
            torch.setdefault(m[1], []).append(float(m[2]))
print("\n| network | backend | Burn (criterion median) | PyTorch CPU (before, after) | Burn / PyTorch |")
print("|---|---|---|---|---|")
for name, ts in torch.items():
    for backend in ("flex", "tch"):
        est = pathlib.Path("target/criterion/train_step") / f"{name.replace('/', '_')}_{backend}" / "new/estimates.json"
        if backend == "tch" and not (log / "tch").exists():
            continue
        burn = json.loads(est.read_text())["median"]["point_estimate"] / 1e9
        mean = sum(ts) / len(ts)
        print(f"| {name} | {backend} | {burn:.3f} s | {', '.join(f'{t:.3f}' for t in ts)} s | {burn / mean:.2f}× |")
PY
