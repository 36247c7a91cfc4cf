#!/usr/bin/env bash
# Issue 26 (links, halo reads): fine-all against multi-source and fine-sources on 4 logical
# devices of one H200, multiscopic 384x216 on Sponza, with two builds side by side. For each
# build and scheme: render.json (GPU span, copies and bytes a frame, links, host staging) and
# the log of 3 frames after 1, and the wall time of a second run of one frame and no warm-up
# (`first_frame`: start-up, the first frame and writing its outputs), and where the build writes
# render.json's `startup`, when each step of the start ended. A run past LIMIT seconds
# is stopped and recorded as such (rc=124).
# SCHEMES (environment, default all three) limits the schemes, to fit one device call.
#   usage: [SCHEMES="fine-all"] issue26_schemes_4dev.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT_FOLDER [LIMIT]
set -uo pipefail
base=$1 new=$2 scene=$3 out=$4 limit=${5:-300}
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
mkdir -p "$out"
for build in base new; do
  bin=${!build}
  for scheme in ${SCHEMES:-multi-source fine-sources fine-all}; do
    dir="$out/$build/$scheme"
    mkdir -p "$dir"
    start=$(date +%s.%N)
    timeout "$limit" "$bin" -v render "${sp[@]}" --lf multiscopic --resolution 384x216 --spp 1 \
      --frames 3 --warmup 1 --fake-devices 4 --scheme "$scheme" --out-dir "$dir/lf" \
      > "$dir/render.log" 2>&1
    rc=$?
    end=$(date +%s.%N)
    echo "$build $scheme rc=$rc wall_s=$(echo "$end - $start" | bc)" | tee -a "$out/summary.txt"
    start=$(date +%s.%N)
    timeout "$limit" "$bin" -q render "${sp[@]}" --lf multiscopic --resolution 384x216 --spp 1 \
      --frames 1 --warmup 0 --fake-devices 4 --scheme "$scheme" --out-dir "$dir/first" \
      > "$dir/first.log" 2>&1
    first_rc=$?
    echo "  first_frame rc=$first_rc wall_s=$(echo "$(date +%s.%N) - $start" | bc)" | tee -a "$out/summary.txt"
    rm -rf "$dir/first"
    [ -f "$dir/lf/render.json" ] && cp "$dir/lf/render.json" "$dir/" && rm -rf "$dir/lf"
    if [ -f "$dir/render.json" ]; then
      python3 - "$dir/render.json" <<'PY' | tee -a "$out/summary.txt"
import json, sys
j = json.load(open(sys.argv[1]))
t, p = j["timing"], j["plan"]
links = j.get("links", {})
print(f"  GPU span {t['frame_gpu']['mean_ms']:.2f} ms, wall {j['wall_ms_per_frame']:.2f} ms/frame, "
      f"{t['copies_per_frame']:.0f} copies {t['copy_bytes_per_frame']/1e6:.1f} MB a frame, "
      f"halo rows {p.get('halo_rows', '-')}, host staging "
      f"{links.get('host_staging_bytes', 0)/2**20:.1f} MiB, links {[l['kind'] for l in links.get('pairs', [])]}")
s = j.get("startup")
if s:
    print(f"  startup: first frame done {s['first_frame_ms']:.0f} ms after the start (planned {s['planned_ms']:.0f}, "
          f"scene {s['scene_loaded_ms']:.0f}, devices {s['devices_ms']:.0f}, executor {s['executor_ms']:.0f})")
PY
    fi
  done
done
