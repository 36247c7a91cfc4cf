#!/usr/bin/env bash
# Issue 26 item 2 (links): two builds side by side on 4 logical devices of one H200, Sponza.
#   schemes: multi-source, fine-sources, fine-all at multiscopic 384x216 (3 frames after 1):
#            GPU span, copies and bytes a frame, link kinds, host and device staging; and the
#            wall time of a run of one frame and no warm-up (`first_frame`: start-up to done).
#   kinds:   (new build only) fine-all at 384x216 with each --link kind forced: gpu (device
#            memory + GPU waits), shared (device memory + relayed signals), relay (host memory
#            + relayed signals, today's path), separating what memory and signalling cost.
#   full:    fine-all at full multiscopic size, 20 frames (after 1), both builds.
#   nelf:    fine-all on the NELF light field (--lf nelf), 20 frames (after 1), both builds.
#   copy:    bench-copy between two logical devices, 64 MiB; the new build measures each kind.
# PARTS (environment, default all five) picks parts, to fit one device call (10 min) each:
#   e.g. PARTS=schemes, then PARTS="kinds copy", then PARTS=full, then PARTS=nelf.
# Every render's summary adds its submissions and cross-device waits a frame per device and
# its copy stage per device (render.json `links.devices`, `timing.stages`).
# Wall times are measured with python3 (the device has no `bc`).
# A run past LIMIT seconds is stopped and recorded as such (rc=124).
#   usage: [PARTS="schemes kinds full nelf copy"] issue26_links_h200.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT_FOLDER [LIMIT]
set -uo pipefail
base=$1 new=$2 scene=$3 out=$4 limit=${5:-240}
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
mkdir -p "$out"
summary="$out/summary.txt"

# summarise RENDER_JSON: GPU span, wall, copies, links, staging.
summarise() {
  python3 - "$1" <<'PY' | tee -a "$summary"
import json, sys
j = json.load(open(sys.argv[1]))
t, links = j["timing"], j.get("links", {})
kinds = sorted({l["kind"] for l in links.get("pairs", [])})
print(f"  GPU span {t['frame_gpu']['mean_ms']:.2f} ms (median {t['frame_gpu']['median_ms']:.2f}), "
      f"wall {j['wall_ms_per_frame']:.2f} ms/frame, {t['copies_per_frame']:.0f} copies "
      f"{t['copy_bytes_per_frame']/1e6:.1f} MB a frame, links {kinds} x{len(links.get('pairs', []))}, "
      f"host staging {links.get('host_staging_bytes', 0)/2**20:.1f} MiB, "
      f"device staging {links.get('device_staging_bytes', 0)/2**20:.1f} MiB")
for d in links.get("devices", []):
    copy = sum(s["mean_ms"] for s in t["stages"] if s["stage"] == "copy" and s["device"] == d["device"])
    print(f"    device {d['device']}: {d['submissions_per_frame']} submissions, "
          f"{d['cross_device_waits_per_frame']} cross-device waits a frame; copy {copy:.2f} ms")
PY
}

# now: seconds since the epoch (fractional); since START: seconds elapsed, 2 decimals.
now() { python3 -c 'import time; print(time.time())'; }
since() { python3 -c 'import sys, time; print(f"{time.time() - float(sys.argv[1]):.2f}")' "$1"; }

# render BUILD NAME FRAMES WARMUP EXTRA_ARGS...: one render into $out/BUILD/NAME.
render() {
  local build=$1 name=$2 frames=$3 warmup=$4
  shift 4
  local bin=${!build} dir="$out/$build/$name"
  mkdir -p "$dir"
  local start
  start=$(now)
  timeout "$limit" "$bin" -v render "${sp[@]}" --spp 1 --frames "$frames" --warmup "$warmup" \
    --fake-devices 4 --out-dir "$dir/lf" "$@" > "$dir/render.log" 2>&1
  local rc=$?
  echo "$build $name rc=$rc wall_s=$(since "$start")" | tee -a "$summary"
  grep -m1 "staging:" "$dir/render.log" | sed 's/^/  log: /' | tee -a "$summary"
  [ -f "$dir/lf/render.json" ] && cp "$dir/lf/render.json" "$dir/" && rm -rf "$dir/lf"
  [ -f "$dir/render.json" ] && summarise "$dir/render.json"
}

# first_frame BUILD NAME EXTRA_ARGS...: wall time from start to one frame written.
first_frame() {
  local build=$1 name=$2
  shift 2
  local bin=${!build} dir="$out/$build/$name"
  mkdir -p "$dir"
  local start
  start=$(now)
  timeout "$limit" "$bin" -q render "${sp[@]}" --spp 1 --frames 1 --warmup 0 --fake-devices 4 \
    --out-dir "$dir/first" "$@" > "$dir/first.log" 2>&1
  local rc=$?
  echo "  $build $name first_frame rc=$rc wall_s=$(since "$start")" | tee -a "$summary"
  rm -rf "$dir/first"
}

for part in ${PARTS:-schemes kinds full nelf copy}; do
  case $part in
    schemes)
      for build in base new; do
        for scheme in multi-source fine-sources fine-all; do
          render "$build" "$scheme" 3 1 --lf multiscopic --resolution 384x216 --scheme "$scheme"
          first_frame "$build" "$scheme" --lf multiscopic --resolution 384x216 --scheme "$scheme"
        done
      done ;;
    kinds)
      for kind in gpu shared relay; do
        render new "fine-all-$kind" 3 1 --lf multiscopic --resolution 384x216 --scheme fine-all --link "$kind"
      done ;;
    full)
      for build in base new; do
        render "$build" fine-all-full 20 1 --lf multiscopic --scheme fine-all
      done ;;
    nelf)
      for build in base new; do
        render "$build" fine-all-nelf 20 1 --lf nelf --scheme fine-all
      done ;;
    copy)
      for build in base new; do
        bin=${!build}
        mkdir -p "$out/$build"
        timeout "$limit" "$bin" bench-copy --fake-devices 2 --size-mib 64 --frames 30 \
          --json "$out/$build/copy.json" 2>&1 | tee "$out/$build/copy.log" | grep -E "link|copy" | sed "s/^/$build: /" \
          | tee -a "$summary"
      done ;;
    *) echo "unknown part $part (schemes, kinds, full, nelf, copy)" >&2; exit 2 ;;
  esac
done
