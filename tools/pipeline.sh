#!/usr/bin/env bash
# `make run`: the whole rotavat pipeline on the committed sample scene; inputs are never modified.
# usage: tools/pipeline.sh ROTAVAT SAMPLE_DIR OUT_DIR
set -euo pipefail
rotavat=$1
scene=$2/scene
out=$3
# `out` is replaced only when it is this pipeline's own (rotavat's marker) or empty: never a user's folder.
if [ -d "$out" ] && [ -n "$(ls -A "$out")" ] && [ ! -f "$out/.rotavat-output" ]; then
  echo "error: $out exists and rotavat did not write it; move it away or run 'make run OUT=another_dir'" >&2
  exit 2
fi
rm -rf "$out"
mkdir -p "$out"
echo '{"written_by": "rotavat", "command": "make run"}' > "$out/.rotavat-output"

echo "== 1. inspect the HPS prediction ($scene/pred)"
"$rotavat" info "$scene/pred"

echo "== 2. calibrate the camera from the people (2D feet/heads only)"
"$rotavat" calibrate "$scene/pred" --out "$out/camera.yaml"

echo "== 3. RotAvat: re-seat every mesh on the ground"
"$rotavat" align "$scene/pred" --camera "$out/camera.yaml" --out "$out/pred_aligned"

echo "== 4. evaluate before and after against the ground truth"
"$rotavat" eval "$scene/pred" "$out/pred_aligned" --gt "$scene/gt" --out "$out/eval"

echo "== 4b. the same before/after without ground truth, as for a video of your own: each against its scene's ground"
"$rotavat" eval "$scene/pred" "$out/pred_aligned" --out "$out/eval_no_gt"

echo "== 5. render the before/after figure (rows: prediction, aligned, ground truth; the truth as a ghost over the others)"
# each row in its own camera: the prediction in the estimated one (--camera), the aligned output in the camera it
# was aligned with, the ground truth in the true one (gt/camera.yaml)
"$rotavat" render "$scene/pred" "$out/pred_aligned" "$scene/gt" --camera "$out/camera.yaml" --ghost gt --frames 0 \
  --size 480 270 --out "$out/figure"

echo "== 5b. every frame as one animated glTF scene (Blender: File > Import > glTF 2.0)"
"$rotavat" export "$out/pred_aligned" --out "$out/scene.glb"

echo "== 6. a 3D recording over time: the same rows in one world, the camera and its uncertainty (Rerun, rotavat[view])"
if "$(dirname "$rotavat")/python" -c "import rerun" 2>/dev/null; then
  "$rotavat" view "$scene/pred" "$out/pred_aligned" --gt "$scene/gt" --camera "$out/camera.yaml" --out "$out/view.rrd"
  view_line="  view.rrd             the 3D recording: open it with  $(dirname "$rotavat")/rerun $out/view.rrd"
else
  view_line="  (no view.rrd: the Rerun SDK is not installed; pip install 'rotavat[view]')"
  echo "$view_line"
fi

echo
echo "outputs in $out/:"
echo "  camera.yaml          the estimated camera"
echo "  pred_aligned/        aligned meshes (npz), camera.yaml, people.csv"
echo "  eval/metrics.md      before/after metrics (also metrics.json)"
echo "  eval_no_gt/metrics.md  before/after without ground truth: feet height, penetration, lean, sliding, stature"
echo "  scene.glb            every frame as one animated glTF scene: people, ground, camera (open in Blender; docs/export.md)"
echo "  figure/000000.png    front/side/top views: prediction, aligned, ground truth (errors in the row captions)"
echo "$view_line"
exit 0
