#!/usr/bin/env bash
# The main job of README.md: set-up, then the most complete thing Parallax does so far:
# plan the NELF light field over 4 devices with the proposed multi-source scheme and draw the
# schedule; then path trace a light field of the embedded default scene over 2 logical devices
# (lavapipe on a machine without a GPU; add --gpus N instead of --fake-devices on a GPU box).
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup.sh
mkdir -p out
cargo build --release
./target/release/parallax plan --lf nelf --gpus 4 --scheme multi-source --assign compact \
  --dot out/plan_nelf_4gpu.dot --json out/plan_nelf_4gpu.json
dot -Tsvg out/plan_nelf_4gpu.dot -o out/plan_nelf_4gpu.svg
echo "wrote out/plan_nelf_4gpu.{dot,json,svg}"
./target/release/parallax render --lf 8x4 --resolution 128x96 --spacing 0.05 --spp 8 \
  --fake-devices 2 --scheme multi-source --out-dir out/lightfield --trace out/lightfield/trace.json
