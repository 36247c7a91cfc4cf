#!/usr/bin/env bash
# Issue 27's picture, two builds side by side on one GPU, Sponza multiscopic, still camera:
#  - every view after 10 frames against a 128-spp reference of every view (FLIP, PSNR, SSIM,
#    mean ratio; compare's auto exposure, the display exposure);
#  - view 50 after 10 and after 100 frames against a REF50_SPP-spp reference of view 50;
#  - the PNGs of view 50 (new build, 10 and 100 frames) and the error grid, to look at.
# Outputs under OUT_FOLDER: <build>_f<frames>_<all|v50>.json (compare's JSON), summary.txt and
# pictures.tar (PNGs).
#   usage: issue27_quality_h200.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT_FOLDER
#   environment: REF_SPP (default 128), REF50_SPP (default 1024); EXTRA, options added to every
#   render and reference (EXTRA="--resolution 32x18" for a quick run on lavapipe)
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
"$base" -q reference "${sp[@]}" --lf multiscopic --spp "${REF_SPP:-128}" --gpus 1 --out-dir "$work/ref"
"$base" -q reference "${sp[@]}" --lf multiscopic --views 50 --spp "${REF50_SPP:-1024}" --gpus 1 --out-dir "$work/ref50"
figures() { # compare JSON -> one line of its overall figures
  python3 - "$1" <<'PY'
import json, sys
o = json.load(open(sys.argv[1]))["comparison"]["overall"]
print(f"FLIP {o['flip']:.4f}, SSIM {o['ssim']:.4f}, PSNR tm {o['psnr_tonemapped_db']:.3f} dB, "
      f"PSNR lin {o['psnr_linear_db']:.3f} dB, mean ratio {', '.join(f'{r:.4f}' for r in o['mean_ratio'])}")
PY
}
for build in base new; do
  bin=${!build}
  for frames in 10 100; do
    dir="$work/$build-f$frames"
    "$bin" -q render "${sp[@]}" --lf multiscopic --still --spp 1 --gpus 1 --frames "$frames" --warmup 0 --out-dir "$dir"
    if [ "$frames" = 10 ]; then
      "$bin" -q compare "$dir" "$work/ref" --json "$out/${build}_f${frames}_all.json" \
        ${ERROR_GRID:+--error-grid "$work/${build}_grid.png"}
      echo "$build f$frames all: $(figures "$out/${build}_f${frames}_all.json")" >> "$summary"
    fi
    "$bin" -q compare --allow-mismatch "$dir/view_050.exr" "$work/ref50/view_050.exr" --json "$out/${build}_f${frames}_v50.json"
    echo "$build f$frames v50: $(figures "$out/${build}_f${frames}_v50.json")" >> "$summary"
    cp "$dir/view_050.png" "$work/${build}_f${frames}_view050.png"
    rm -rf "$dir"
  done
done
cp "$work/ref50/view_050.png" "$work/ref50_view050.png" 2>/dev/null || true
(cd "$work" && tar cf "$out/pictures.tar" *.png)
cat "$summary"
