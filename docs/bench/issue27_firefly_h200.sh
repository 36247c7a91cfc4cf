#!/usr/bin/env bash
# Issue 27, firefly suppression: the base build, the new build (fireflies suppressed, the
# default) and the new build with `--fireflies keep`, side by side on one GPU, Sponza
# multiscopic:
#  - still camera: every view after 10 frames against a REF_SPP-spp reference of every view,
#    view 50 after 1, 10 and 100 frames against a REF50_SPP-spp reference of view 50 (FLIP, SSIM,
#    PSNR, per-channel mean ratio; compare's automatic exposure, the display exposure);
#  - frame time: `render --spp 1 --gpus 1 --frames 20 --warmup 5`, moving camera (GPU span, wall,
#    the stages, firefly_bound and firefly_spread among them);
#  - the PNGs of view 50 after 10 and 100 frames of each run and of the reference;
#  - whether new's EXRs equal base's bit for bit (`cmp`), after 10 still frames and after the
#    moving camera's 20 frames: when the base build already suppresses fireflies (main from
#    fc29ed4 on), a change that keeps the passes' arithmetic (the shared-memory tiles) must say
#    "identical".
# Outputs under OUT_FOLDER: <run>_f<frames>_<all|v50>.json (compare's JSON), <run>_timing.json
# (render.json's timing), summary.txt, pictures.tar.
#   usage: issue27_firefly_h200.sh BASE_BINARY NEW_BINARY SPONZA_GLTF OUT_FOLDER
#   environment: REF_SPP (default 128), REF50_SPP (default 1024); EXTRA, options added to every
#   render and reference (EXTRA="--resolution 96x54" for a quick run on lavapipe); LF (default
#   multiscopic) and VIEW (default 50: the view compared alone; LF=3x1 VIEW=1 on lavapipe);
#   QUICK=1: no references and no quality figures, only 10 still frames (for the bit check)
#   and the timing runs.
set -euo pipefail
base=$1 new=$2 scene=$3 out=$4
lf=${LF:-multiscopic}
view=${VIEW:-50}
name=$(printf 'view_%03d' "$view")
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
read -r -a extra <<< "${EXTRA:-}"
sp+=("${extra[@]}")
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
summary=$out/summary.txt
: > "$summary"
quick=${QUICK:-0}
if [ "$quick" = 1 ]; then
  still_frames=(10)
else
  still_frames=(1 10 100)
  "$new" -q reference "${sp[@]}" --lf "$lf" --spp "${REF_SPP:-128}" --gpus 1 --out-dir "$work/ref"
  "$new" -q reference "${sp[@]}" --lf "$lf" --views "$view" --spp "${REF50_SPP:-1024}" --gpus 1 --out-dir "$work/ref1"
fi
figures() { # compare JSON -> one line of its overall figures
  python3 - "$1" <<'PY'
import json, sys
o = json.load(open(sys.argv[1]))["comparison"]["overall"]
print(f"FLIP {o['flip']:.4f}, SSIM {o['ssim']:.4f}, PSNR tm {o['psnr_tonemapped_db']:.3f} dB, "
      f"PSNR lin {o['psnr_linear_db']:.3f} dB, mean ratio {', '.join(f'{r:.4f}' for r in o['mean_ratio'])}")
PY
}
timing() { # render.json -> frame time and the stages, one line
  python3 - "$1" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
t = r["timing"]
stages = ", ".join(f"{s['stage']} {s['mean_ms']:.2f}" for s in t["stages"])
print(f"GPU span {t['frame_gpu']['mean_ms']:.2f} ms, wall {r['wall_ms_per_frame']:.2f} ms; {stages}")
PY
}
same_exrs() { # two render folders -> whether every EXR is equal bit for bit, one line
  local differ=0 total=0 exr
  for exr in "$1"/*.exr; do
    [ -e "$exr" ] || { echo "no EXRs in $1"; return; }
    total=$((total + 1))
    cmp -s "$exr" "$2/$(basename "$exr")" || differ=$((differ + 1))
  done
  if [ "$differ" = 0 ]; then echo "identical ($total EXRs)"; else echo "$differ of $total EXRs differ"; fi
}
# run name -> binary and extra flags
declare -A bin=([base]=$base [new]=$new [keep]=$new)
declare -A flags=([base]="" [new]="" [keep]="--fireflies keep")
for run in base new keep; do
  read -r -a f <<< "${flags[$run]}"
  for frames in "${still_frames[@]}"; do
    dir="$work/$run-f$frames"
    "${bin[$run]}" -q render "${sp[@]}" "${f[@]}" --lf "$lf" --still --spp 1 --gpus 1 --frames "$frames" \
      --warmup 0 --out-dir "$dir"
    if [ "$frames" = 10 ] && [ "$quick" != 1 ]; then
      "$new" -q compare "$dir" "$work/ref" --json "$out/${run}_f${frames}_all.json"
      echo "$run f$frames all: $(figures "$out/${run}_f${frames}_all.json")" >> "$summary"
    fi
    if [ "$quick" != 1 ]; then
      "$new" -q compare --allow-mismatch "$dir/$name.exr" "$work/ref1/$name.exr" --json "$out/${run}_f${frames}_v$view.json"
      echo "$run f$frames v$view: $(figures "$out/${run}_f${frames}_v$view.json")" >> "$summary"
    fi
    [ "$frames" = 1 ] || cp "$dir/$name.png" "$work/${run}_f${frames}_$name.png"
    if [ "$run" = new ] && [ "$frames" = 10 ]; then
      echo "new f10 against base, bit for bit: $(same_exrs "$dir" "$work/base-f10")" >> "$summary"
      rm -rf "$work/base-f10"
    fi
    # base's 10 still frames stay for new's bit check
    [ "$run" = base ] && [ "$frames" = 10 ] || rm -rf "$dir"
  done
  dir="$work/$run-timing"
  "${bin[$run]}" -q render "${sp[@]}" "${f[@]}" --lf "$lf" --spp 1 --gpus 1 --frames 20 --warmup 5 --out-dir "$dir"
  python3 -c 'import json,sys; json.dump(json.load(open(sys.argv[1]))["timing"], open(sys.argv[2], "w"))' \
    "$dir/render.json" "$out/${run}_timing.json"
  echo "$run timing: $(timing "$dir/render.json")" >> "$summary"
  if [ "$run" = new ]; then
    echo "new timing run against base, bit for bit: $(same_exrs "$dir" "$work/base-timing")" >> "$summary"
    rm -rf "$work/base-timing"
  fi
  [ "$run" = base ] || rm -rf "$dir"
done
cp "$work/ref1/$name.png" "$work/ref_$name.png" 2>/dev/null || true
(cd "$work" && tar cf "$out/pictures.tar" ./*.png)
cat "$summary"
