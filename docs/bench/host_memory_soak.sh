#!/usr/bin/env bash
# Host memory of a long run (issue 30): multiscopic 384x216 on Sponza, 3,000 measured frames
# after 100 of warm-up, one GPU. Samples the process's resident set every second from outside
# (/proc/PID/status VmRSS, with the time since start) into rss.csv, beside render.json's own
# host_memory figures over the measured frames.
#   usage: host_memory_soak.sh PARALLAX_BINARY SPONZA_GLTF OUT_FOLDER
set -euo pipefail
bin=$1 scene=$2 out=$3
mkdir -p "$out"
run=$(mktemp -d)
"$bin" render --scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5 \
  --sky 0.5,0.6,0.8 --max-depth 6 --lf multiscopic --resolution 384x216 --spp 1 --gpus 1 \
  --still --frames 3000 --warmup 100 --out-dir "$run/lf" 2> "$out/render.log" &
pid=$!
start=$(date +%s%N)
echo "ms,rss_kib" > "$out/rss.csv"
while kill -0 "$pid" 2> /dev/null; do
  rss=$(awk '/^VmRSS:/ { print $2 }' "/proc/$pid/status" 2> /dev/null || true)
  [ -n "$rss" ] && echo "$((($(date +%s%N) - start) / 1000000)),$rss" >> "$out/rss.csv"
  sleep 1
done
wait "$pid"
cp "$run/lf/render.json" "$out/"
cp "$run/lf/lightfield.png" "$out/"
rm -rf "$run"
