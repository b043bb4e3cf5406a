#!/usr/bin/env bash
# All tests: installs what is missing, checks formatting and lints, runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup-debian.sh
# The tests alone need headless Chromium (it loads the HTML session report,
# tests/report_html.rs) and a PostgreSQL server they start themselves (tests/records_postgres.rs).
test_need=()
for pkg in chromium postgresql; do
  dpkg -s "$pkg" >/dev/null 2>&1 || test_need+=("$pkg")
done
if [ ${#test_need[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${test_need[@]}"
fi
export PATH="$HOME/.cargo/bin:$PATH"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/xdg-$(id -u)}"; mkdir -p -m 700 "$XDG_RUNTIME_DIR"
rustup component add rustfmt clippy >/dev/null 2>&1 || true
cargo fmt --all -- --check
cargo clippy --release --locked --workspace --all-targets -- -D warnings
cargo test --release --locked --workspace --all-targets
