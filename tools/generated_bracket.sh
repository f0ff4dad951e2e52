#!/usr/bin/env bash
# A bracket folder of a device whose response, noise and chroma noise are known (hidden from
# the loop), made with `hdrsynth realism` from linear radiance frames: per scene 7 frames one
# stop apart (exposure 2^-5 … 2^1 of the radiance), 8-bit PNGs and OpenCV's list.txt.
#   tools/generated_bracket.sh RADIANCE_DIR OUT [HDRSYNTH] [DEVICE]
# RADIANCE_DIR: linear EXRs (e.g. a main job's data/test_radiance). The hidden device is written
# to OUT.device.toml (beside OUT, so the loop does not scan it): DEVICE (a sensor profile at
# ISO 100) where given, else gamma 1.8 (not sRGB), white noise σ² = 2e-4·x + 2e-6 at ISO 100,
# channels correlated by 0.5, identity colour.
set -euo pipefail
src=$1 out=$2 bin=${3:-target/release/hdrsynth} given=${4:-}
[[ -e $out ]] && { echo "$out exists" >&2; exit 1; }
device=$out.device.toml
if [[ -n $given ]]; then
  cp "$given" "$device"
else
cat > "$device" <<'TOML'
format = "hdrsynth-sensor/1"
name = "hidden device (generated bracket)"
kind = "composite"
effects = [{ id = "channel_correlation", rho = 0.5 }]

[provenance]
colour = "identity (generated)"
noise = "hidden: a = 2e-4, b = 2e-6 at ISO 100, white"
levels = "generated: 10-bit, black 64, white 1023"
response = "hidden: gamma 1.8"

[colour]
matrix = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
use_root_polynomial = false

[levels]
black_level = 64.0
white_level = 1023.0
bit_depth = 10

[[noise]]
iso = 100.0
a = [2e-4, 2e-4, 2e-4]
b = [2e-6, 2e-6, 2e-6]

[response]
kind = "gamma"
gamma = 1.8

[source_response]
kind = "linear"
TOML
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
n=0
for exr in "$src"/*.exr; do
  scene=$(printf "scene_%02d" "$n")
  mkdir -p "$out/$scene"
  : > "$out/$scene/list.txt"
  for k in 0 1 2 3 4 5 6; do
    e=$(python3 -c "print(2.0 ** ($k - 5))")
    "$bin" realism --profile "$device" --iso 100 --in "$exr" --out "$tmp/f" --bits 8 \
      --exposure "$e" --seed $((n * 10 + k)) > /dev/null
    mv "$tmp/f/$(basename "${exr%.exr}").png" "$out/$scene/f$k.png"
    echo "f$k.png $(python3 -c "print(1.0 / $e)")" >> "$out/$scene/list.txt"
  done
  n=$((n + 1))
done
echo "$n scenes in $out; the hidden device: $device"
