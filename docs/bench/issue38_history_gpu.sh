#!/usr/bin/env bash
# Issue 38, the history halo (HISTORY_REACH): the three schemes on 4 logical devices of one GPU,
# two builds side by side in one call (base first, then new, per case). Multiscopic 384x216
# (5 frames after 2), full multiscopic and full NELF (4 after 1), Sponza, 1 spp. Writes per run
# render.json and the log, and one summary line: GPU span / wall ms a frame, copies and MB a
# frame, device staging MiB; for full multiscopic fine-all, view 50's EXR of both builds is
# compared byte for byte. A run past LIMIT seconds is stopped (rc=124).
#   usage: [CASES="small full nelf"] issue38_history_gpu.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT [LIMIT]
set -uo pipefail
base=$1 new=$2 scene=$3 out=$4 limit=${5:-240}
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
mkdir -p "$out"
summary() {
  python3 - "$1" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
t, p = j["timing"], j["plan"]
print(f"  GPU span {t['frame_gpu']['mean_ms']:.2f} ms, wall {j['wall_ms_per_frame']:.2f} ms, "
      f"copies {p.get('cross_device_copies')}, MB {p.get('bytes_per_frame', 0) / 1e6:.1f}, "
      f"staging {j.get('links', {}).get('device_staging_bytes', 0) / 2**20:.0f} MiB")
PY
}
run() { # name lf resolution-args frames warmup scheme
  local name=$1 lf=$2 res=$3 frames=$4 warmup=$5 scheme=$6
  for build in base new; do
    local bin=${!build} dir="$out/$name/$scheme/$build"
    mkdir -p "$dir"
    timeout "$limit" "$bin" -v render "${sp[@]}" --lf "$lf" $res --spp 1 --frames "$frames" \
      --warmup "$warmup" --fake-devices 4 --scheme "$scheme" --out-dir "$dir/lf" > "$dir/render.log" 2>&1
    echo "$name $scheme $build rc=$?" | tee -a "$out/summary.txt"
    if [ -f "$dir/lf/render.json" ]; then
      cp "$dir/lf/render.json" "$dir/"
      summary "$dir/render.json" | tee -a "$out/summary.txt"
    else
      tail -3 "$dir/render.log" | tee -a "$out/summary.txt"
    fi
  done
}
for case in ${CASES:-small full nelf}; do
  case $case in
    small) for s in multi-source fine-sources fine-all; do run small multiscopic "--resolution 384x216" 5 2 "$s"; done ;;
    full) for s in multi-source fine-all; do run full multiscopic "" 4 1 "$s"; done
          cmp "$out/full/fine-all/base/lf/view_050.exr" "$out/full/fine-all/new/lf/view_050.exr" \
            && echo "full fine-all view 50 EXR byte-identical base/new" | tee -a "$out/summary.txt" ;;
    nelf) for s in multi-source fine-all; do run nelf nelf "" 4 1 "$s"; done ;;
  esac
done
find "$out" -name lf -type d -prune -exec rm -rf {} +
