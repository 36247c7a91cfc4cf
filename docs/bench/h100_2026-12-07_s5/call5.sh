#!/usr/bin/env bash
# Call 5 (2026-12-07, fifth session): issue 37 item 3, subsampled hole filling (branch wt37h on
# main e392721) against full hole filling, speed and picture, with the 2567c5a baseline's speed.
S=.scenes/sponza_lite/Sponza.gltf
V=docs/bench/issue37_variants_gpu.sh
PARTS=speed bash $V .gl/bin/parallax-base $S "$OUT/base" base="" > "$OUT/base.log" 2>&1
PARTS="speed accuracy" LIMIT=150 bash $V .gl/bin/parallax-new $S "$OUT/new" views="--denoise views" \
  samples="--denoise samples" samples-sub="--denoise samples --hole-fill subsampled" \
  views-sub="--denoise views --hole-fill subsampled" > "$OUT/new.log" 2>&1
cat "$OUT/base/summary.txt" "$OUT/new/summary.txt" > "$OUT/summaries.txt"
tar czf "$OUT/results.tgz" -C "$OUT" base new base.log new.log && rm -rf "$OUT/base" "$OUT/new" "$OUT/base.log" "$OUT/new.log"
