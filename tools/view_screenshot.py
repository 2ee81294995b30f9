"""Driver for tools/view_screenshot.sh: screenshot a running headless Rerun viewer.

It talks to a viewer started with `rerun --headless --bind 127.0.0.1 --port PORT FILE.rrd`
through the viewer-control API of the rerun SDK (`rerun.experimental.ViewerClient`, rerun-sdk
0.41), so it needs nothing but the venv's rerun-sdk and Pillow. Steps:

1. connect (retrying until the viewer's gRPC port answers);
2. wait until the viewer reports nothing left loading, an active recording and a view;
3. optionally move the time cursor (FRAME) and pause playback;
4. take screenshots until N successive ones are pixel-identical and not a single flat colour
   (so transient toasts and a frame still being drawn are not captured), then write the PNG.

Run through tools/view_screenshot.sh, which starts and stops the viewer; see that header.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import os
import sys
import time

import numpy as np
from PIL import Image


def log(msg: str) -> None:
    print(f"view_screenshot: {msg}", file=sys.stderr, flush=True)


_viewer_pid: int | None = None


def viewer_alive() -> None:
    """Fail at once if the viewer process is gone (a panic, e.g. no usable Vulkan adapter)."""
    if _viewer_pid is None:
        return
    try:
        os.kill(_viewer_pid, 0)
        with open(f"/proc/{_viewer_pid}/stat") as f:
            if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                raise ProcessLookupError
    except (ProcessLookupError, FileNotFoundError):
        raise SystemExit("view_screenshot: the viewer exited before the screenshot was taken") from None


def connect(url: str, deadline: float):
    from rerun.experimental import ViewerClient

    if not hasattr(ViewerClient, "take_screenshot"):
        raise SystemExit("view_screenshot: this rerun-sdk is too old (needs ViewerClient.take_screenshot, 0.41)")
    last: Exception | None = None
    while time.monotonic() < deadline:
        try:
            client = ViewerClient.connect(url)
            client.get_state()
            return client
        except Exception as err:  # the port is not up yet
            last = err
            viewer_alive()
            time.sleep(0.1)
    raise SystemExit(f"view_screenshot: the viewer at {url} never answered: {last}")


def wait_loaded(client, deadline: float):
    """The viewer state once the recording is loaded and has a view."""
    empty_since: float | None = None
    state = None
    while time.monotonic() < deadline:
        viewer_alive()
        state = client.get_state()
        loaded = not state.loading and state.active_recording is not None and state.views
        if loaded:
            return state
        if not state.loading and state.active_recording is None:
            # Nothing is loading and nothing got opened: usually an unreadable file.
            empty_since = empty_since or time.monotonic()
            if time.monotonic() - empty_since > 5:
                logs = client.get_logs()
                errors = [e.message for e in logs if e.level == "ERROR"] or [
                    e.message for e in logs if e.level == "WARN"
                ]
                raise SystemExit(
                    "view_screenshot: the viewer opened no recording; it logged:\n  "
                    + "\n  ".join(errors[-10:] or ["(none)"])
                )
        time.sleep(0.2)
    what = [s.status for s in state.loading] if state else "?"
    raise SystemExit(f"view_screenshot: timed out waiting for the recording to load (still loading: {what})")


def set_frame(client, state, frame: str, timeline: str | None) -> str:
    """Move the time cursor as FRAME asks; returns a description of where it is."""
    rec = next(r for r in state.recordings if r.store_id == state.active_recording)
    if frame == "keep":
        return f"{rec.current_timeline}={rec.current_time} (viewer default)"
    name = timeline or rec.current_timeline or (rec.timelines[0].name if rec.timelines else None)
    tl = next((t for t in rec.timelines if t.name == name), None)
    if tl is None:
        raise SystemExit(
            f"view_screenshot: no timeline {name!r} in the recording; it has {[t.name for t in rec.timelines]}"
        )
    if frame == "first":
        value = tl.start
    elif frame == "last":
        value = tl.end
    else:
        try:
            value = int(frame)
        except ValueError:
            raise SystemExit(f"view_screenshot: FRAME must be keep, first, last or an integer, not {frame!r}")
    if value is None:
        raise SystemExit(f"view_screenshot: timeline {name!r} holds no data")
    # FRAME is in the timeline's own unit: a sequence index, or nanoseconds for time timelines.
    if tl.time_type == "sequence":
        client.set_time(name, sequence=value, play_state="paused")
    elif tl.time_type == "duration":
        client.set_time(name, duration=np.timedelta64(value, "ns"), play_state="paused")
    else:
        client.set_time(name, timestamp=np.datetime64(value, "ns"), play_state="paused")
    return f"{name}={value}"


def pick_view(state, view: str) -> str | None:
    if view == "all":
        return None
    for v in state.views:
        if v.visible and (v.name == view or v.view_id == view or v.view_class.lower() == view.lower()):
            return v.view_id
    raise SystemExit(
        f"view_screenshot: no visible view named or of class {view!r}; views: "
        + ", ".join(f"{v.name!r} ({v.view_class})" for v in state.views)
    )


def settle(client, view_id: str | None, deadline: float, needed: int, interval: float) -> tuple[bytes, int, bool]:
    """Screenshot until `needed` successive ones are identical and not a flat colour.

    Returns the last screenshot, how many were taken, and whether the picture settled.
    """
    prev, same, shots, png = None, 0, 0, b""
    while time.monotonic() < deadline:
        png = client.take_screenshot(view_id)
        shots += 1
        pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3)
        flat = len(pixels) == 0 or bool((pixels == pixels[0]).all())
        digest = hashlib.sha1(pixels.tobytes()).digest()
        same = 0 if flat else (same + 1 if digest == prev else 1)
        prev = digest
        if same >= needed:
            return png, shots, True
        time.sleep(interval)
    return png, shots, False


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", required=True, help="rerun+http://127.0.0.1:PORT/proxy")
    ap.add_argument("--out", required=True)
    ap.add_argument("--timeout", type=float, default=90.0)
    ap.add_argument("--frame", default="keep", help="keep | first | last | N (timeline units)")
    ap.add_argument("--timeline", default=None)
    ap.add_argument("--view", default="all", help="all (whole viewer) | a view name | a view class such as 3D")
    ap.add_argument("--stable", type=int, default=3, help="identical successive screenshots required")
    ap.add_argument("--interval", type=float, default=0.3)
    ap.add_argument("--viewer-pid", type=int, default=None, help="fail fast if this process exits")
    args = ap.parse_args()
    global _viewer_pid
    _viewer_pid = args.viewer_pid

    t0 = time.monotonic()
    deadline = t0 + args.timeout
    client = connect(args.url, deadline)
    state = wait_loaded(client, deadline)
    where = set_frame(client, state, args.frame, args.timeline)
    for v in state.views:
        for r in v.reports:
            log(f"view {v.name!r}: {r.severity}: {r.summary}")
    view_id = pick_view(state, args.view)
    png, shots, settled = settle(client, view_id, deadline, args.stable, args.interval)
    if not png:
        raise SystemExit("view_screenshot: timed out before the first screenshot")
    with open(args.out, "wb") as f:
        f.write(png)
    if not settled:
        raise SystemExit(
            f"view_screenshot: the picture did not settle in {shots} screenshots (a playing/looping timeline?"
            f" try FRAME=last); the last one is in {args.out}"
        )
    w, h = Image.open(io.BytesIO(png)).size
    views = ", ".join(f"{v.name!r} ({v.view_class})" for v in state.views if v.visible)
    log(
        f"wrote {args.out} ({w}x{h}) at {where}; views: {views}; "
        f"{shots} screenshots, {time.monotonic() - t0:.1f}s after start"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
