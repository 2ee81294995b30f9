#!/usr/bin/env bash
# Best effort: the EGL/Mesa libraries the OpenGL renderer uses. Without them rotavat renders
# with its numpy fallback, so a failure here never stops the build.
if ldconfig -p 2>/dev/null | grep -q "libEGL.so.1" && ldconfig -p 2>/dev/null | grep -q "libGL.so.1"; then
  exit 0
fi
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing libegl1 libegl-mesa0 libgl1-mesa-dri for the OpenGL renderer"
  (apt-get update -qq && apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri) >/dev/null 2>&1 \
    || echo "could not install EGL libraries: rotavat render will use its numpy fallback"
else
  echo "EGL libraries not found: rotavat render will use its numpy fallback"
fi
exit 0
