#!/bin/bash
# The Network-2 recipe ablation of docs/experiments.md ("Recipe"): the main job's Net_S with
# one change of its recipe undone at a time (Wu's image head, LDR^2.2 inputs, training scenes
# with moving subjects) or one option added (the loss in the reference unit, the kernel head
# instead of the merge head), per seed: the DSLR pretraining, then
# Net_S's fine-tuning, scored on the main job's test sets. Resumable: a finished variant and
# seed is kept. Analyse with tools/recipe_ablation.py.
#
#   tools/recipe_ablation.sh QUICKSTART_DIR OUT_DIR [HDRSYNTH_BINARY]
set -euo pipefail
Q=$(realpath "$1"); OUT=$(realpath -m "$2"); B=${3:-target/release/hdrsynth}
B=$(realpath "$B")
mkdir -p "$OUT"
# Training scenes with moving subjects: the main job's, motion as the scene engine's default.
if [ ! -d "$OUT/dynamic_train" ]; then
  sed 's/^motion_scale = 0.0/motion_scale = 1.0/' "$Q/configs/train_data.toml" > "$OUT/dynamic_train.toml"
  "$B" generate --config "$OUT/dynamic_train.toml" --out "$OUT/dynamic_train"
fi
target=$(ls "$Q"/configs/sensors/*.toml | grep -v dslr_canon_550d_gamma22 | head -1)
for v in image gamma22 reference_unit dynamic kernel; do
  for k in 1 2 3; do
    d=$OUT/$v/seed$k; mkdir -p "$d"
    [ -f "$d/ev_primary/summary.csv" ] && continue
    sed "s#$Q/pretrain/seed$k#$d/pre#" "$Q/configs/pretrain_seed$k.toml" > "$d/pre.toml"
    sed -e "s#$Q/unused#$d/ft#" -e "s#^seed = 0#seed = $k#" -e "s#$Q/pretrain/seed1#$d/pre#" \
        -e "s#^profile = \"pure\"#profile = \"$target\"#" "$Q/configs/finetune.toml" > "$d/ft.toml"
    for f in "$d/pre.toml" "$d/ft.toml"; do
      case $v in
        image) sed -i 's/^output = "merge"/output = "image"/' "$f";;
        gamma22) sed -i 's/^linearise = "data"/linearise = "fixed"/' "$f";;
        reference_unit) sed -i 's/^\[loss\]$/[loss]\nhdr_unit = "reference"/' "$f";;
        dynamic) sed -i "s#$Q/data/train#$OUT/dynamic_train#" "$f";;
        kernel) sed -i 's/^output = "merge"/output = "kernel"/' "$f";;
      esac
    done
    for run in pre ft; do
      if [ -d "$d/$run" ]; then "$B" train --config "$d/$run.toml" --resume; else "$B" train --config "$d/$run.toml"; fi > "$d/$run.log" 2>&1
    done
    for t in testset_real_radiance testset_real_capture; do
      if [ -d "$Q/data/$t" ]; then
        rm -rf "$d/ev_$t"; "$B" eval --testset "$Q/data/$t" --checkpoint "$d/ft" --out "$d/ev_$t" > /dev/null
      fi
    done
    rm -rf "$d/ev_primary"
    "$B" eval --testset "$Q/data/testset/seed$k" --checkpoint "$d/ft" --out "$d/ev_primary" > /dev/null
  done
done
