#!/usr/bin/env bash
# The paper's three experiments at the quickstart's (CPU) scale, with seeds 1–3
# (configs/experiments/cpu/README.md). Every stage resumes; results are deterministic.
#   bash tools/cpu_experiments.sh [exp1|exp2|exp3|decomp|phone_b|curves ...]  (default: all)
# Needs ../shared/data/real_hdr for the test scenes. Writes under runs/cpu/.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${BIN:-target/release/hdrsynth}
[ -x "$bin" ] || cargo build --release
cfg=configs/experiments/cpu
want=("$@"); [ ${#want[@]} -gt 0 ] || want=(exp2 exp3 exp1 decomp phone_b curves)
# Train a pretraining config unless its run already reached run.steps (resume if interrupted).
pretrain() {
  local config=$1 out steps latest
  out=$(sed -n 's/^out = "\(.*\)"/\1/p' "$config" | head -1)
  steps=$(sed -n 's/^steps = //p' "$config" | head -1)
  if [ -f "$out/checkpoints/latest" ]; then
    latest=$(cat "$out/checkpoints/latest")
    grep -qx "step = $steps" "$out/checkpoints/$latest/state.toml" && return 0
    "$bin" train --config "$config" --resume
  else
    "$bin" train --config "$config"
  fi
}
for e in "${want[@]}"; do
  case "$e" in
    exp1) pretrain "$cfg/net1_pretrain.toml"
          "$bin" ablate --config "$cfg/exp1_network1.toml" ;;
    exp2) pretrain "$cfg/net2_pretrain.toml"
          "$bin" ablate --config "$cfg/exp2_network2.toml" ;;
    exp3) pretrain "$cfg/net2_pretrain.toml"
          "$bin" ablate --config "$cfg/exp3_network2_colour_iso.toml" ;;
    decomp) pretrain "$cfg/net2_pretrain.toml"
          "$bin" ablate --config "$cfg/exp3b_what_the_gain_is.toml" ;;
    curves) pretrain "$cfg/net1_pretrain_literal.toml" ;;
    phone_b) pretrain "$cfg/net2_pretrain.toml"
          "$bin" ablate --config "$cfg/exp2_phone_b.toml" ;;
    *) echo "unknown experiment '$e' (exp1, exp2, exp3, decomp, phone_b, curves)" >&2; exit 2 ;;
  esac
done
