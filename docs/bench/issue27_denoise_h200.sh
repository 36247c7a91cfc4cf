#!/usr/bin/env bash
# Issue 27 item 1 (a denoiser at the memory limit), two builds side by side on one GPU, Sponza:
#  - time: `render $SP --lf L --spp 1 --gpus 1 --frames 20 --warmup 5` for L = multiscopic and
#    nelf, base and new alternating twice (base, new, base, new), render.json's GPU span, wall
#    time and per-stage means of the SVGF passes (svgf_history, svgf_temporal, svgf_atrous_1..5);
#  - picture: every view after 10 still frames against a 128-spp reference of every view, and
#    new's views against base's (same samples: what the denoiser change alone does), FLIP, SSIM,
#    PSNR and mean ratio at compare's auto exposure.
# Outputs under OUT_FOLDER: time.tsv (one line per run and stage), <build>_f10_all.json and
# new_vs_base_f10.json (compare's JSON), summary.txt.
#   usage: issue27_denoise_h200.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT_FOLDER
#   environment: REF_SPP (default 128); FRAMES and WARMUP of the timed runs (default 20 and 5);
#   EXTRA, options added to every render and reference (EXTRA="--resolution 16x9" with FRAMES=2
#   WARMUP=1 REF_SPP=16 for a quick run of the script on lavapipe); SKIP_PICTURE=1 for time only,
#   SKIP_TIME=1 for the picture only
set -euo pipefail
base=$1 new=$2 scene=$3 out=$4
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
read -r -a extra <<< "${EXTRA:-}"
sp+=("${extra[@]}")
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
summary=$out/summary.txt
times=$out/time.tsv
: > "$summary"
printf 'layout\tbuild\trun\tstage\tms\n' > "$times"

stages() { # render.json -> tab-separated lines: frame GPU span, wall, each SVGF stage, their sum
  python3 - "$1" <<'PY'
import json, sys
o = json.load(open(sys.argv[1]))
t = o["timing"]
print(f"frame_gpu\t{t['frame_gpu']['mean_ms']:.3f}")
print(f"frame_wall\t{o['wall_ms_per_frame']:.3f}")
svgf = 0.0
for s in t["stages"]:
    if s["stage"].startswith("svgf"):
        svgf += s["mean_ms"]
        print(f"{s['stage']}\t{s['mean_ms']:.3f}")
print(f"svgf_total\t{svgf:.3f}")
PY
}

for lf in multiscopic nelf; do
  [ -n "${SKIP_TIME:-}" ] && break
  for run in 1 2; do
    for build in base new; do
      bin=${!build}
      dir="$work/t-$lf-$build-$run"
      "$bin" -q render "${sp[@]}" --lf "$lf" --spp 1 --gpus 1 --frames "${FRAMES:-20}" --warmup "${WARMUP:-5}" --out-dir "$dir"
      stages "$dir/render.json" | sed "s/^/$lf\t$build\t$run\t/" >> "$times"
      rm -rf "$dir"
    done
  done
done
[ -n "${SKIP_TIME:-}" ] || python3 - "$times" >> "$summary" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
for lf in ("multiscopic", "nelf"):
    for stage in ("frame_gpu", "frame_wall", "svgf_total", "svgf_temporal", "svgf_atrous_1",
                  "svgf_atrous_2", "svgf_atrous_3", "svgf_atrous_4", "svgf_atrous_5"):
        cells = []
        for build in ("base", "new"):
            ms = [float(r["ms"]) for r in rows if r["layout"] == lf and r["build"] == build and r["stage"] == stage]
            cells.append(" / ".join(f"{m:.2f}" for m in ms) or "-")
        print(f"{lf} {stage}: base {cells[0]}, new {cells[1]} ms")
PY

if [ -z "${SKIP_PICTURE:-}" ]; then
  figures() { # compare JSON -> one line of its overall figures
    python3 - "$1" <<'PY'
import json, sys
o = json.load(open(sys.argv[1]))["comparison"]["overall"]
f = lambda v, d: f"{v:.{d}f}" if isinstance(v, (int, float)) else str(v)  # PSNR of equal images: "inf"
print(f"FLIP {f(o['flip'], 4)}, SSIM {f(o['ssim'], 4)}, PSNR tm {f(o['psnr_tonemapped_db'], 3)} dB, "
      f"PSNR lin {f(o['psnr_linear_db'], 3)} dB, mean ratio {', '.join(f(r, 6) for r in o['mean_ratio'])}")
PY
  }
  "$base" -q reference "${sp[@]}" --lf multiscopic --spp "${REF_SPP:-128}" --gpus 1 --out-dir "$work/ref"
  for build in base new; do
    bin=${!build}
    "$bin" -q render "${sp[@]}" --lf multiscopic --still --spp 1 --gpus 1 --frames 10 --warmup 0 --out-dir "$work/$build-f10"
    "$bin" -q compare "$work/$build-f10" "$work/ref" --json "$out/${build}_f10_all.json"
    echo "$build f10 all vs reference: $(figures "$out/${build}_f10_all.json")" >> "$summary"
  done
  "$new" -q compare "$work/new-f10" "$work/base-f10" --json "$out/new_vs_base_f10.json"
  echo "new vs base f10 all: $(figures "$out/new_vs_base_f10.json")" >> "$summary"
fi
cat "$summary"
