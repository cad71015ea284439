#!/usr/bin/env bash
# Build and run every test of the workspace in release mode (training tests need optimized code).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --release --workspace --locked "$@"
