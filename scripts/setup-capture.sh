#!/usr/bin/env bash
# What `snerf capture` and its tests need, from Debian: COLMAP 3.8 (`colmap`, run headless on
# the CPU), ffmpeg (frames from a video, `snerf capture --video`) and visp-images-data (GPL-2;
# real camera frames for the tests: ViSP-images/cube/, 80 greyscale frames of a table scene from
# a robot-held camera, and mbt-depth/castel/castel/, 30 frames of a castle model with its
# calibrated camera). Idempotent: installs only what is missing. Needs root for apt-get.
# Exits non-zero when COLMAP is still missing afterwards.
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
command -v colmap >/dev/null
