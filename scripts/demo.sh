#!/usr/bin/env bash
# Main job: installs what is missing, builds, and runs the headless demo into ./vesalius-demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup-debian.sh
export PATH="$HOME/.cargo/bin:$PATH"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/xdg-$(id -u)}"; mkdir -p -m 700 "$XDG_RUNTIME_DIR"
cargo build --release --locked
./target/release/vesalius demo --out vesalius-demo
# The supervisor's window, playing the same trace on a virtual screen, saved as a screenshot.
xvfb-run -a -s "-screen 0 1920x1080x24" ./target/release/vesalius run nephrectomy \
  --trace assets/traces/nephrectomy-demo.toml --screenshot vesalius-demo/window.png
