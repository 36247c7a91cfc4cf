#!/usr/bin/env bash
# Issue 37, item 4: how far the first still frames' per-channel mean is from the reference, and
# which stage moves it. Sponza multiscopic at full size, 1 spp, --gpus 1, every view compared
# with a REF_SPP reference of every view (compare's mean ratio: test mean / reference mean, R G B).
# Variants, each from frame 1 (no warm-up):
#   path-trace   every view path traced, no denoiser: the estimator itself (unbiased by design);
#   no-denoise   sources + reprojection + hole filling + firefly suppression, no SVGF;
#   pipeline     the whole pipeline, after 1, 2, 4 and 10 frames.
# One summary line a run; view 50's PNG of each run and the reference's contact sheet kept in
# pictures.tar to look at.
#   usage: issue37_first_frames_gpu.sh BINARY SPONZA_GLTF OUT
#   environment: REF_SPP (default 128); EXTRA, options added to every render and the reference
#   (EXTRA="--resolution 48x27" for a quick run on lavapipe)
set -euo pipefail
bin=$1 scene=$2 out=$3
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6 --lf multiscopic)
read -r -a extra <<< "${EXTRA:-}"
sp+=("${extra[@]}")
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
summary=$out/summary.txt
"$bin" -q reference "${sp[@]}" --spp "${REF_SPP:-128}" --gpus 1 --out-dir "$work/ref"
cp "$work/ref/reference.png" "$work/ref_contact_sheet.png"
measure() { # label frames render-options...
  local label=$1 frames=$2
  shift 2
  local dir="$work/$label-f$frames"
  "$bin" -q render "${sp[@]}" --still --spp 1 --gpus 1 --frames "$frames" --warmup 0 "$@" --out-dir "$dir"
  "$bin" -q compare "$dir" "$work/ref" --json "$out/${label}_f${frames}.json" > /dev/null
  python3 - "$out/${label}_f${frames}.json" "$label f$frames" >> "$summary" <<'PY'
import json, sys
o = json.load(open(sys.argv[1]))["comparison"]["overall"]
print(f"{sys.argv[2]}: mean ratio {', '.join(f'{r:.4f}' for r in o['mean_ratio'])}, FLIP {o['flip']:.4f}")
PY
  cp "$dir/view_050.png" "$work/${label}_f${frames}_view050.png"
  rm -rf "$dir"
}
measure path-trace 1 --pipeline path-trace --no-denoise
measure no-denoise 1 --no-denoise
for frames in 1 2 4 10; do measure pipeline "$frames"; done
(cd "$work" && tar cf "$out/pictures.tar" ./*.png)
cat "$summary"
