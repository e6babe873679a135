#!/usr/bin/env bash
# Make sure Mesa's headless EGL (OpenGL without a display) is present; install it with
# apt-get when we can (root on Debian/Ubuntu), otherwise say exactly what is missing.
set -euo pipefail
PKGS="libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri"
have_egl() { ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so' && ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1'; }
if have_egl; then exit 0; fi
if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
  echo "installing Mesa EGL: $PKGS"
  apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $PKGS >/dev/null
elif command -v apt-get >/dev/null 2>&1 && command -v sudo >/dev/null 2>&1; then
  sudo apt-get update -qq >/dev/null && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $PKGS >/dev/null
else
  echo "treeform needs Mesa EGL for headless rendering; install: $PKGS" >&2
  exit 1
fi
