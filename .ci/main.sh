#!/usr/bin/env bash
# The main job of README.md: set-up, then the most complete thing Parallax does so far.
# Today: plan the NELF light field over 4 devices with the proposed multi-source scheme, check
# the schedule, and draw it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup.sh
mkdir -p out
cargo run --release -- plan --lf nelf --gpus 4 --scheme multi-source --assign compact \
  --dot out/plan_nelf_4gpu.dot --json out/plan_nelf_4gpu.json
dot -Tsvg out/plan_nelf_4gpu.dot -o out/plan_nelf_4gpu.svg
echo "wrote out/plan_nelf_4gpu.{dot,json,svg}"
