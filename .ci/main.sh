#!/usr/bin/env bash
# The main job of README.md: set-up, then a light field of the embedded default scene through the
# paper's full reconstruction pipeline (G-buffer, path tracing of the sources, reprojection, hole
# filling, SVGF, tonemapping) over 2 logical devices under the proposed multi-source scheme, for
# 8 measured frames of a camera dolly (lavapipe on a machine without a GPU; use --gpus N instead of
# --fake-devices on a GPU box); and the plan of the NELF light field over 4 devices, drawn.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup.sh
mkdir -p out/lightfield
cargo build --release
./target/release/parallax render --lf 8x4 --resolution 128x96 --spacing 0.05 --spp 1 \
  --fake-devices 2 --scheme multi-source --frames 8 --warmup 2 --motion dolly --quilt --layers \
  --out-dir out/lightfield --trace out/lightfield/trace.json
./target/release/parallax plan --lf nelf --gpus 4 --scheme multi-source --assign compact \
  --dot out/plan_nelf_4gpu.dot --json out/plan_nelf_4gpu.json
dot -Tsvg out/plan_nelf_4gpu.dot -o out/plan_nelf_4gpu.svg
echo "wrote out/lightfield/ (view EXRs, lightfield.png, the quilt, render.json, trace.json) and out/plan_nelf_4gpu.{json,dot,svg}"
