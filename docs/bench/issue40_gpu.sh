#!/usr/bin/env bash
# Issue 40 on one GPU machine (H100 or H200): MPI ranks on the GPU against one process, a killed
# rank, and bench-rays with its own flags.
#   1. For each scheme: one process over 3 logical devices (--fake-devices 3) and `mpirun -n 3`
#      with one GPU a rank (--gpus 1; the three ranks share the machine's one GPU), 8x4 views of
#      256x192 of the default scene, 8 frames after 2; every view's EXR and PNG and the contact
#      sheet compared byte for byte, and each run's frame time from render.json.
#   2. A 3-rank run of 100,000 frames with rank 2 killed (SIGKILL) 3 s after it started: the
#      exit status and what the run prints.
#   3. bench-rays on the default scene and on Sponza (SPONZA, optional) with its default
#      schedules, 1024x1024, 9 repeats: diffuse, primary and any-hit rays/s.
# Needs: BIN, a release build with --features mpi (default .bin/parallax-mpi); mpirun on the PATH
# (the image's own OpenMPI, else Debian's unpacked from .mpi/*.deb by the caller).
#   usage: BIN=... OUT=... [SPONZA=...] [SCHEMES="" SKIP_RAYS=1: the killed rank alone] bash docs/bench/issue40_gpu.sh
set -uo pipefail
BIN=${BIN:-.bin/parallax-mpi}
OUT=${OUT:-out/issue40}
mkdir -p "$OUT"
MPI=(mpirun --allow-run-as-root --oversubscribe --bind-to none -n 3)
RENDER=(render --lf 8x4 --resolution 256x192 --spp 1 --frames 8 --warmup 2 -q)
mpirun --version 2>&1 | head -1 | tee "$OUT/mpi_version.txt"

frame_ms() {
  python3 -c "import json,sys; j=json.load(open(sys.argv[1])); t=j['timing']; \
print(f\"GPU span {t['frame_gpu']['mean_ms']:.2f} ms, wall {j['wall_ms_per_frame']:.2f} ms/frame\")" "$1/render.json"
}

for scheme in ${SCHEMES-multi-source fine-sources fine-all}; do
  one="$OUT/one_$scheme" ranks="$OUT/ranks_$scheme"
  timeout 240 "$BIN" "${RENDER[@]}" --scheme "$scheme" --fake-devices 3 --out-dir "$one" > "$one.log" 2>&1
  echo "one process, 3 logical devices, $scheme: rc=$? $(frame_ms "$one")"
  timeout 240 "${MPI[@]}" "$BIN" "${RENDER[@]}" --scheme "$scheme" --gpus 1 --out-dir "$ranks" > "$ranks.log" 2>&1
  echo "mpirun -n 3 --gpus 1, $scheme: rc=$? $(frame_ms "$ranks")"
  differ=0 compared=0
  for f in "$one"/view_*.exr "$one"/view_*.png "$one"/lightfield.png; do
    compared=$((compared + 1))
    cmp -s "$f" "$ranks/$(basename "$f")" || { differ=$((differ + 1)); echo "  differs: $(basename "$f")"; }
  done
  echo "  $compared files compared byte for byte, $differ differ"
done 2>&1 | tee "$OUT/ranks.txt"

# A rank killed mid-run: rank 2 is found by OpenMPI's OMPI_COMM_WORLD_RANK in its environment.
(
  "${MPI[@]}" "$BIN" render --lf 8x4 --resolution 256x192 --spp 1 --frames 100000 --warmup 2 \
    --scheme multi-source --gpus 1 --out-dir "$OUT/killed" > "$OUT/killed.log" 2>&1
  echo "rc=$?" >> "$OUT/killed.log"
) &
runner=$!
killed=""
for _ in $(seq 1 600); do
  for pid in $(pgrep -f "$BIN render --lf 8x4 --resolution 256x192 --spp 1 --frames 100000"); do
    if tr '\0' '\n' < "/proc/$pid/environ" 2>/dev/null | grep -qx OMPI_COMM_WORLD_RANK=2; then
      # Killed once frames are under way (the devices and the scene are up by then).
      sleep 3; kill -9 "$pid" && killed=$pid
      break 2
    fi
  done
  sleep 0.1
done
wait "$runner"
{ echo "killed rank 2 (pid ${killed:-none found})"; cat "$OUT/killed.log"; ls "$OUT/killed" 2>&1 | head -3; } | tee "$OUT/killed.txt"

[ -n "${SKIP_RAYS:-}" ] || {
  "$BIN" bench-rays --scene default --resolution 1024x1024 --repeats 9 --json "$OUT/rays_default.json"
  if [ -n "${SPONZA:-}" ]; then
    "$BIN" bench-rays --scene "$SPONZA" --resolution 1024x1024 --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 \
      --repeats 9 --json "$OUT/rays_sponza.json"
  fi
} 2>&1 | tee "$OUT/rays.txt"
