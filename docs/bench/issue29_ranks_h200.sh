#!/usr/bin/env bash
# Issue 29 on one H200: a render over R = 1, 2, 4 MPI ranks of 4/R logical devices each against
# one process with 4 logical devices (multiscopic 384x216, multi-source, as docs/RESULTS.md's
# "Schemes on four logical devices"): time per frame, each rank's GPU time, and the bytes each
# rank sent rank 0, beside what `plan --ranks R` predicts per frame.
#
# What it needs (the H200 machine has no MPI and no internet):
#   - a parallax binary built WITH the feature, on a machine that has libopenmpi-dev and
#     libclang-dev:  cargo build --release --features mpi   (PARALLAX_BIN, default
#     target/release/parallax); it links libmpi.so.40 dynamically;
#   - on the H200, OpenMPI 4.1's runtime. The H200 image (2026-12-03) has its own OpenMPI 4.1.6
#     (/usr/bin/mpirun, libmpi.so.40): use it as it is. Unpacking Debian's 4.1.4 over it made
#     mpirun crash in libpmix before any rank started. Only where none is installed: `mpirun`
#     (Debian openmpi-bin) and libmpi.so.40
#     (libopenmpi3) with their libraries (libpmix2, libhwloc15, libevent-core/pthreads, libfabric1,
#     libucx0, libpsm2-2, libibverbs1, ...). On a Debian 12 box with internet:
#       apt-get download openmpi-bin openmpi-common libopenmpi3 libpmix2 libhwloc15 libevent-2.1-7 \
#         libevent-core-2.1-7 libevent-pthreads-2.1-7 libfabric1 libucx0 libpsm2-2 libibverbs1 \
#         librdmacm1 libnl-3-200 libnl-route-3-200 libxnvctrl0 libpsm-infinipath1 ocl-icd-libopencl1
#     then on the H200: dpkg -i *.deb  (or unpack with dpkg -x into a prefix and set PATH,
#     LD_LIBRARY_PATH and OPAL_PREFIX to it). This script checks both and says what is missing.
#   - PARALLAX_SPONZA (optional): Sponza's glTF; the default scene otherwise.
# Runs as root on the device machine: mpirun needs --allow-run-as-root; --oversubscribe lets
# R ranks share fewer cores.
set -euo pipefail
BIN=${PARALLAX_BIN:-target/release/parallax}
OUT=${OUT:-out/issue29}
SCENE=${PARALLAX_SPONZA:-default}

if ! command -v mpirun >/dev/null; then
  echo "error: mpirun not found: install OpenMPI's runtime (openmpi-bin, libopenmpi3; see the top of $0)" >&2
  exit 2
fi
if [ ! -x "$BIN" ]; then
  echo "error: $BIN not found: build it with cargo build --release --features mpi (or set PARALLAX_BIN)" >&2
  exit 2
fi
if ldd "$BIN" | grep -q "not found"; then
  echo "error: $BIN misses libraries (OpenMPI's runtime, see the top of $0):" >&2
  ldd "$BIN" | grep "not found" >&2
  exit 2
fi
if ! ldd "$BIN" | grep -q libmpi; then
  echo "error: $BIN was built without --features mpi: every rank would render alone" >&2
  exit 2
fi

mkdir -p "$OUT"
RENDER=(render --scene "$SCENE" --lf multiscopic --resolution 384x216 --scheme multi-source --spp 1
        --frames 20 --warmup 5 -q)
MPI=(mpirun --allow-run-as-root --oversubscribe --bind-to none)

echo "== one process, 4 logical devices"
timeout 300 "$BIN" "${RENDER[@]}" --fake-devices 4 --out-dir "$OUT/one_4dev"
for R in 1 2 4; do
  G=$((4 / R))
  echo "== $R rank(s) x $G logical device(s)"
  "$BIN" -q plan --lf multiscopic --resolution 384x216 --scheme multi-source --fake-devices 4 --ranks "$R" \
    --json "$OUT/plan_r$R.json" >/dev/null
  timeout 300 "${MPI[@]}" -n "$R" "$BIN" "${RENDER[@]}" --fake-devices "$G" --out-dir "$OUT/r${R}x$G"
done

# The table: wall and GPU ms per frame, per rank GPU ms and bytes sent, the plan's bytes per frame.
python3 - "$OUT" <<'PY'
import json, sys, os
out = sys.argv[1]
def load(p):
    with open(os.path.join(out, p)) as f:
        return json.load(f)
print("| run | wall ms/frame | GPU span ms (rank 0) | per rank GPU ms | bytes sent (last frame) | plan: display + linear bytes/frame |")
print("|---|---:|---:|---|---|---|")
one = load("one_4dev/render.json")
print(f"| 1 process x 4 | {one['wall_ms_per_frame']:.2f} | {one['timing']['frame_gpu']['mean_ms']:.2f} | - | - | - |")
for r in (1, 2, 4):
    j = load(f"r{r}x{4 // r}/render.json")
    plan = load(f"plan_r{r}.json").get("ranks", [])
    planned = " / ".join(f"{p['display_bytes_per_frame']}+{p['linear_bytes_per_frame']}" for p in plan)
    ranks = (j.get("ranks") or {}).get("per_rank", [])
    gpu = " / ".join(f"{x['frame_gpu_ms']:.2f}" for x in ranks) or "-"
    sent = " / ".join(str(x["bytes_sent"]) for x in ranks) or "-"
    print(f"| {r} rank(s) x {4 // r} | {j['wall_ms_per_frame']:.2f} | {j['timing']['frame_gpu']['mean_ms']:.2f} | {gpu} | {sent} | {planned} |")
PY
# The views must equal the one-process run's, bit for bit.
for R in 2 4; do
  for f in "$OUT"/one_4dev/view_*.exr; do
    cmp -s "$f" "$OUT/r${R}x$((4 / R))/$(basename "$f")" || echo "DIFFERS: $(basename "$f") at R=$R"
  done
done
echo "views compared (no DIFFERS line: bit for bit)"
