#!/usr/bin/env bash
# What `snerf capture` and its tests need, from Debian: COLMAP 3.8 (`colmap`, run headless on
# the CPU), ffmpeg (frames from a video, `snerf capture --video`) and visp-images-data (GPL-2;
# real camera frames for the tests: ViSP-images/cube/, 80 greyscale frames of a table scene from
# a robot-held camera, and mbt-depth/castel/castel/, 30 frames of a castle model with its
# calibrated camera); then PyPI's pycolmap 4.2.1 (COLMAP 4 bindings, the capture's default
# backend when present) into target/capture-venv, pinned by wheel SHA-256
# (scripts/capture-requirements.txt; CPython 3.11 on x86_64 Linux, elsewhere the capture keeps
# Debian's colmap). Idempotent: installs only what is missing. Needs root for apt-get.
# Exits non-zero when no COLMAP (neither) is usable afterwards.
set -euo pipefail

missing=()
command -v colmap >/dev/null || missing+=(colmap)
command -v ffmpeg >/dev/null || missing+=(ffmpeg)
[ -d /usr/share/visp-images-data/ViSP-images/cube ] || missing+=(visp-images-data)
if [ ${#missing[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    echo "setup-capture: missing ${missing[*]}; install them with apt-get (as root)" >&2
  fi
fi

here="$(cd "$(dirname "$0")" && pwd)"
venv="$here/../target/capture-venv"
if ! "$venv/bin/python" -c "import pycolmap" 2>/dev/null; then
  if python3 -m venv "$venv" && "$venv/bin/pip" install -q --disable-pip-version-check --require-hashes \
      -r "$here/capture-requirements.txt"; then
    echo "setup-capture: pycolmap $("$venv/bin/python" -c 'import pycolmap; print(pycolmap.__version__)') in $venv" >&2
  else
    echo "setup-capture: pycolmap not installed (its pinned wheels are for CPython 3.11 on x86_64); snerf capture uses Debian's colmap" >&2
  fi
fi
command -v colmap >/dev/null || "$venv/bin/python" -c "import pycolmap" 2>/dev/null
