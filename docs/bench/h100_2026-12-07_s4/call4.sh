#!/usr/bin/env bash
# Call 4 (2026-12-07, fourth session): issue 39's no-slower check (2567c5a vs main 140c903), then
# issue 38's refusal of NELF fine-all on 4 logical devices of one GPU.
S=.scenes/sponza_lite/Sponza.gltf
bash docs/bench/issue39_no_slower_gpu.sh .gl/bin/parallax-base .gl/bin/parallax-new $S "$OUT/slow" 150 > "$OUT/slow.log" 2>&1
mkdir -p "$OUT/refuse"
SECONDS=0
.gl/bin/parallax-new render --scene $S --lf nelf --scheme fine-all --fake-devices 4 --frames 2 --warmup 1 \
  --out-dir /tmp/refuse-out > "$OUT/refuse/stdout.txt" 2> "$OUT/refuse/stderr.txt"
echo "rc=$? seconds=$SECONDS" > "$OUT/refuse/rc.txt"
ls -la /tmp/refuse-out >> "$OUT/refuse/rc.txt" 2>&1
.gl/bin/parallax-new devices > "$OUT/refuse/devices.txt" 2>&1
