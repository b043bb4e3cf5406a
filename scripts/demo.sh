#!/usr/bin/env bash
# Main job: installs what is missing, builds, and runs the headless demo into ./vesalius-demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup-debian.sh
export PATH="$HOME/.cargo/bin:$PATH"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/xdg-$(id -u)}"; mkdir -p -m 700 "$XDG_RUNTIME_DIR"
cargo build --release --locked
./target/release/vesalius demo --out vesalius-demo
