#!/usr/bin/env bash
# Issue 37: the pipeline's variants (denoiser placement, G-buffer kind) as points of a
# speed-against-accuracy chart, one binary, one GPU, Sponza, 1 spp, --gpus 1.
#   speed:    multiscopic and NELF at full size, 10 frames after 2: GPU span, wall and the stages;
#   accuracy: multiscopic, still camera from frame 1: every view after 1 and 10 frames against a
#             REF_SPP reference of every view, view 50 after 10 and 100 frames against a
#             REF50_SPP reference of view 50 (compare: FLIP, mean ratio R G B).
# Writes OUT/points.jsonl (one JSON object a variant and figure), OUT/summary.txt, the compare
# JSONs and OUT/pictures.tar (view 50 of every run and of the references, to look at).
#   usage: issue37_variants_gpu.sh BINARY SPONZA_GLTF OUT LABEL=OPTIONS...
#     e.g. views="--denoise views" samples="--denoise samples --gbuffer visibility"
#   environment: REF_SPP (128), REF50_SPP (1024), PARTS ("speed accuracy"), LIMIT (120 s a run),
#   EXTRA (options added to every render, e.g. "--resolution 48x27" on lavapipe)
set -uo pipefail
bin=$1 scene=$2 out=$3
shift 3
sp=(--scene "$scene" --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    --sky 0.5,0.6,0.8 --max-depth 6)
read -r -a extra <<< "${EXTRA:-}"
sp+=("${extra[@]}")
limit=${LIMIT:-120}
mkdir -p "$out/pictures"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
point() { # label figure json-file-or-value... -> one line of points.jsonl and summary.txt
  python3 - "$@" <<'PY' | tee -a "$OUT_DIR/summary.txt" >&2
import json, sys
label, kind, path = sys.argv[1:4]
j = json.load(open(path))
if kind == "speed":
    t = j["timing"]
    p = {"variant": label, "figure": "speed", "lf": sys.argv[4], "gpu_ms": t["frame_gpu"]["mean_ms"],
         "wall_ms": j["wall_ms_per_frame"], "gbuffer": j.get("gbuffer"), "denoise": j.get("denoise"),
         "stages": {r["stage"]: r["mean_ms"] for r in t["stages"]}}
else:
    o = j["comparison"]["overall"]
    p = {"variant": label, "figure": kind, "flip": o["flip"], "mean_ratio": o["mean_ratio"]}
with open(sys.argv[-1], "a") as f:
    f.write(json.dumps(p) + "\n")
print(json.dumps({k: v for k, v in p.items() if k != "stages"}))
PY
}
export OUT_DIR=$out
for part in ${PARTS:-speed accuracy}; do
  if [ "$part" = accuracy ]; then
    timeout 300 "$bin" -q reference "${sp[@]}" --lf multiscopic --spp "${REF_SPP:-128}" --gpus 1 --out-dir "$work/ref"
    timeout 120 "$bin" -q reference "${sp[@]}" --lf multiscopic --views 50 --spp "${REF50_SPP:-1024}" --gpus 1 --out-dir "$work/ref50"
    cp "$work/ref/reference.png" "$out/pictures/ref_contact_sheet.png"
    cp "$work/ref50/reference.png" "$out/pictures/ref50_view050.png"
  fi
  for variant in "$@"; do
    label=${variant%%=*}
    read -r -a opts <<< "${variant#*=}"
    if [ "$part" = speed ]; then
      for lf in multiscopic nelf; do
        dir="$work/$label-$lf"
        timeout "$limit" "$bin" -q render "${sp[@]}" --lf "$lf" --spp 1 --frames 10 --warmup 2 --gpus 1 \
          "${opts[@]}" --out-dir "$dir" > "$out/$label-$lf.log" 2>&1
        echo "$label $lf rc=$?" >> "$out/summary.txt"
        [ -f "$dir/render.json" ] && cp "$dir/render.json" "$out/$label-$lf.json" \
          && point "$label" speed "$dir/render.json" "$lf" "$out/points.jsonl"
        rm -rf "$dir"
      done
    else
      for frames in 1 10 100; do
        dir="$work/$label-f$frames"
        timeout "$limit" "$bin" -q render "${sp[@]}" --lf multiscopic --still --spp 1 --gpus 1 --frames "$frames" \
          --warmup 0 "${opts[@]}" --out-dir "$dir" > "$out/$label-f$frames.log" 2>&1
        echo "$label f$frames rc=$?" >> "$out/summary.txt"
        if [ "$frames" != 100 ]; then
          "$bin" -q compare "$dir" "$work/ref" --json "$out/${label}_f${frames}_all.json" > /dev/null \
            && point "$label" "all_f$frames" "$out/${label}_f${frames}_all.json" "$out/points.jsonl"
        fi
        if [ "$frames" != 1 ]; then
          "$bin" -q compare --allow-mismatch "$dir/view_050.exr" "$work/ref50/view_050.exr" \
            --json "$out/${label}_f${frames}_v50.json" > /dev/null \
            && point "$label" "v50_f$frames" "$out/${label}_f${frames}_v50.json" "$out/points.jsonl"
        fi
        cp "$dir/view_050.png" "$out/pictures/${label}_f${frames}_view050.png" 2>/dev/null
        rm -rf "$dir"
      done
    fi
  done
done
(cd "$out" && tar cf pictures.tar pictures && rm -rf pictures)
