#!/usr/bin/env bash
# Issue 37, item 2: the compute visibility G-buffer against traced first hits on one GPU, two
# builds in one call (BASE has only traced first hits). Multiscopic and NELF at full size,
# Sponza, 1 spp, 8 frames after 2, --gpus 1. One summary line a run: GPU span and wall ms a frame,
# the G-buffer stages' ms a frame (gbuffer; visibility_raster + visibility_resolve), and the
# G-buffer that ran (render.json's gbuffer, gbuffer_fallback); view 50's EXR of visibility and
# first hits compared byte for byte.
#   usage: issue37_gbuffer_gpu.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT [LIMIT]
set -uo pipefail
base=$1 new=$2 scene=$3 out=$4 limit=${5:-240}
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
mkdir -p "$out"
summary() {
  python3 - "$1" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
t = j["timing"]
stage = lambda s: sum(r["mean_ms"] for r in t["stages"] if r["stage"] == s)
print(f"  GPU span {t['frame_gpu']['mean_ms']:.2f} ms, wall {j['wall_ms_per_frame']:.2f} ms, "
      f"gbuffer {stage('gbuffer'):.2f}, visibility_raster {stage('visibility_raster'):.2f}, "
      f"visibility_resolve {stage('visibility_resolve'):.2f} ms; ran {j.get('gbuffer')} "
      f"fallback {j.get('gbuffer_fallback')}")
print("  stages: " + ", ".join(f"{r['stage']} {r['mean_ms']:.2f}" for r in t["stages"]))
PY
}
run() { # lf build gbuffer-args label
  local lf=$1 build=$2 args=$3 label=$4 bin=${!2} dir="$out/$1/$4"
  mkdir -p "$dir"
  timeout "$limit" "$bin" -v render "${sp[@]}" --lf "$lf" --spp 1 --frames 8 --warmup 2 --gpus 1 \
    $args --out-dir "$dir/lf" > "$dir/render.log" 2>&1
  echo "$lf $label rc=$?" | tee -a "$out/summary.txt"
  if [ -f "$dir/lf/render.json" ]; then
    cp "$dir/lf/render.json" "$dir/"
    summary "$dir/render.json" | tee -a "$out/summary.txt"
  else
    tail -3 "$dir/render.log" | tee -a "$out/summary.txt"
  fi
}
for lf in multiscopic nelf; do
  run "$lf" base "" base
  run "$lf" new "--gbuffer first-hits" first-hits
  run "$lf" new "--gbuffer visibility" visibility
  cmp "$out/$lf/first-hits/lf/view_050.exr" "$out/$lf/visibility/lf/view_050.exr" \
    && echo "$lf view 50 EXR byte-identical first-hits/visibility" | tee -a "$out/summary.txt"
  mkdir -p "$out/$lf/pictures"
  for l in first-hits visibility; do cp "$out/$lf/$l/lf/view_050.exr" "$out/$lf/pictures/$l.exr" 2>/dev/null; done
done
find "$out" -name lf -type d -prune -exec rm -rf {} +
