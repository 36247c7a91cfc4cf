#!/usr/bin/env bash
# Issue 39's no-slower check on one GPU: BASE and NEW builds alternately (base, new, base, new)
# on the multiscopic and NELF light fields at full size, Sponza, 1 spp, 20 frames after 5,
# --gpus 1, the default pipeline. One summary line a run (GPU span and wall ms a frame), every
# stage's ms a frame, and NEW's view EXRs compared byte for byte with BASE's.
#   usage: issue39_no_slower_gpu.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT [LIMIT]
set -uo pipefail
base=$1 new=$2 scene=$3 out=$4 limit=${5:-180}
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
mkdir -p "$out"
summary() {
  python3 - "$1" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
t = j["timing"]
print(f"  GPU span {t['frame_gpu']['mean_ms']:.2f} ms, wall {j['wall_ms_per_frame']:.2f} ms")
print("  stages: " + ", ".join(f"{r['stage']} {r['mean_ms']:.2f}" for r in t["stages"]))
PY
}
for lf in multiscopic nelf; do
  for round in 1 2; do
    for build in base new; do
      bin=${!build} dir="$out/$lf/$build$round"
      mkdir -p "$dir"
      timeout "$limit" "$bin" -v render "${sp[@]}" --lf "$lf" --spp 1 --frames 20 --warmup 5 --gpus 1 \
        --out-dir "$dir/lf" > "$dir/render.log" 2>&1
      echo "$lf $build round $round rc=$?" | tee -a "$out/summary.txt"
      if [ -f "$dir/lf/render.json" ]; then
        cp "$dir/lf/render.json" "$dir/"
        summary "$dir/render.json" | tee -a "$out/summary.txt"
      else
        tail -3 "$dir/render.log" | tee -a "$out/summary.txt"
      fi
    done
  done
  same=0 differ=0
  for f in "$out/$lf/new1/lf"/view_*.exr; do
    if cmp -s "$f" "$out/$lf/base1/lf/$(basename "$f")"; then same=$((same + 1)); else differ=$((differ + 1)); fi
  done
  echo "$lf views new1 vs base1: $same byte-identical, $differ differ" | tee -a "$out/summary.txt"
done
find "$out" -name lf -type d -prune -exec rm -rf {} +
