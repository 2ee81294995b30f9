#!/usr/bin/env bash
# Screenshot the Rerun viewer showing an .rrd file, on a headless machine (no screen, no GPU).
#
# usage: tools/view_screenshot.sh RRD OUT.png [WIDTH HEIGHT]
#   WIDTH HEIGHT: the viewer window in logical points, which is also the PNG's size (default 1280 720).
# environment (all optional):
#   FRAME=keep|first|last|N  where to put the time cursor (default keep: the viewer's own choice, which
#                            is the end of the timeline, or its start when the recording's blueprint says
#                            play_state="paused"). N is in the timeline's unit (sequence index, or ns).
#   TIMELINE=NAME            the timeline FRAME refers to (default: the viewer's current one)
#   VIEW=all|NAME|3D         the whole viewer (default), or only one view, by name or by class
#   TIMEOUT=90               seconds before giving up
#   PYTHON=...               the python with rerun-sdk and Pillow (default: the repository's .venv)
#
# How: the native viewer shipped in the rerun-sdk wheel runs with `--headless` (an offscreen egui
# harness; no X server, no Xvfb) and renders with wgpu on Mesa's lavapipe, the CPU Vulkan driver.
# tools/view_screenshot.py then drives it over its localhost gRPC port with rerun-sdk's
# `rerun.experimental.ViewerClient`: it waits until nothing is loading, optionally moves the time
# cursor, and takes screenshots until successive ones are identical, then writes OUT.png.
# The GL backend (--renderer gl) does not work headless ("Failed to get render context").
#
# Needs (this script installs nothing):
#   apt:  mesa-vulkan-drivers   (brings libvulkan1; lavapipe's ICD /usr/share/vulkan/icd.d/lvp_icd.*.json)
#   PyPI: rerun-sdk (0.41 has ViewerClient.take_screenshot) and Pillow, in $PYTHON's environment
# Everything it starts (one `rerun` process) is stopped on exit; its config/analytics state lives in
# a temporary directory, so ~/.config/rerun is neither read nor written.
set -euo pipefail

usage() { echo "usage: $0 RRD OUT.png [WIDTH HEIGHT]" >&2; exit 2; }
[ $# -eq 2 ] || [ $# -eq 4 ] || usage
rrd=$1
out=$2
width=${3:-1280}
height=${4:-720}
[[ $width =~ ^[0-9]+$ && $height =~ ^[0-9]+$ ]] || usage
[[ ${FRAME:-keep} =~ ^(keep|first|last|-?[0-9]+)$ ]] || { echo "error: FRAME must be keep, first, last or an integer" >&2; exit 2; }
[ -f "$rrd" ] || { echo "error: no such file: $rrd" >&2; exit 2; }
rrd=$(realpath "$rrd")
out_dir=$(dirname "$out")
[ -d "$out_dir" ] || { echo "error: no such directory: $out_dir" >&2; exit 2; }
out="$(realpath "$out_dir")/$(basename "$out")"

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
python=${PYTHON:-$here/../.venv/bin/python}

# --- tools ---------------------------------------------------------------------------------------
[ -x "$python" ] || { echo "error: no python at $python (set PYTHON=...)" >&2; exit 3; }
rerun_bin=$("$python" - <<'PY'
import importlib.util, os, sys
for module, package in (("rerun", "rerun-sdk"), ("rerun_cli", "rerun-sdk"), ("PIL", "Pillow"), ("numpy", "numpy")):
    if importlib.util.find_spec(module) is None:
        sys.exit(f"error: missing PyPI package {package} in {sys.executable}'s environment (pip install {package})")
import rerun_cli
print(os.path.join(os.path.dirname(rerun_cli.__file__), "rerun"))
PY
) || exit 3
[ -x "$rerun_bin" ] || { echo "error: rerun-sdk's viewer binary is missing: $rerun_bin (reinstall rerun-sdk)" >&2; exit 3; }
if ! ldconfig -p 2>/dev/null | grep 'libvulkan\.so\.1' >/dev/null || ! compgen -G '/usr/share/vulkan/icd.d/lvp_icd*.json' >/dev/null; then
  echo "error: missing apt package mesa-vulkan-drivers (apt-get install -y mesa-vulkan-drivers)" >&2
  exit 3
fi

# --- start the viewer ----------------------------------------------------------------------------
tmp=$(mktemp -d "${TMPDIR:-/tmp}/view_screenshot.XXXXXX")
viewer_pid=""
driver_pid=""
cleanup() {
  local rc=$?
  if [ -n "$driver_pid" ]; then
    kill -TERM "$driver_pid" 2>/dev/null || true
    wait "$driver_pid" 2>/dev/null || true
  fi
  if [ -n "$viewer_pid" ] && kill -0 "$viewer_pid" 2>/dev/null; then
    kill -TERM "$viewer_pid" 2>/dev/null || true
    for _ in $(seq 50); do kill -0 "$viewer_pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$viewer_pid" 2>/dev/null || true
    wait "$viewer_pid" 2>/dev/null || true
  fi
  if [ "$rc" -ne 0 ] && [ -s "$tmp/viewer.log" ]; then
    echo "--- the viewer's log (panics, errors, warnings):" >&2
    sed 's/\x1b\[[0-9;]*m//g' "$tmp/viewer.log" | grep -E -A1 "panicked|ERROR|WARN" | cut -c1-300 | tail -n 12 >&2 || true
  fi
  rm -rf "$tmp"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

mkdir -m 700 "$tmp/config" "$tmp/data" "$tmp/runtime"
export XDG_CONFIG_HOME=$tmp/config XDG_DATA_HOME=$tmp/data XDG_RUNTIME_DIR=$tmp/runtime
"$rerun_bin" analytics disable >/dev/null 2>&1 || true   # no network here anyway; keeps it quiet

port=$("$python" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
start=$(date +%s.%N)
"$rerun_bin" --headless --bind 127.0.0.1 --port "$port" --window-size "${width}x${height}" \
  --hide-welcome-screen "$rrd" >"$tmp/viewer.log" 2>&1 &
viewer_pid=$!

# --- wait for the scene and take the screenshot ---------------------------------------------------
# In the background plus `wait`, so that a TERM/INT to this script stops it at once (bash runs traps
# only after a foreground command ends).
"$python" "$here/view_screenshot.py" --url "rerun+http://127.0.0.1:$port/proxy" --out "$out" \
  --timeout "${TIMEOUT:-90}" --frame "${FRAME:-keep}" ${TIMELINE:+--timeline "$TIMELINE"} --view "${VIEW:-all}" \
  --viewer-pid "$viewer_pid" &
driver_pid=$!
wait "$driver_pid"
driver_pid=""
echo "view_screenshot: $out in $(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.1f", e - s }')s" >&2
