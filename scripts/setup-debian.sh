#!/usr/bin/env bash
# Installs what a fresh Debian 12 machine needs to build and run Vesalius, when missing.
set -euo pipefail
need=()
# Vulkan: Mesa's lavapipe renders in software where there is no GPU.
# OpenXR: the Khronos loader (and its openxr_runtime_list) that loads our simulated runtime.
# The window: the X11 client libraries winit loads; Xvfb and xdotool for the window's tests.
# procps: the `kill` program the session tests signal with (and --xr-sim forwards signals by).
for pkg in build-essential pkg-config curl ca-certificates procps mesa-vulkan-drivers libvulkan1 vulkan-tools \
    libopenxr-loader1 libopenxr-dev libopenxr-utils \
    libx11-6 libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon0 libxkbcommon-x11-0 \
    xvfb xauth xdotool; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}"
fi
if ! command -v cargo >/dev/null 2>&1; then
  if [ -x "$HOME/.cargo/bin/cargo" ]; then
    export PATH="$HOME/.cargo/bin:$PATH"
  else
    curl -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal
    export PATH="$HOME/.cargo/bin:$PATH"
  fi
fi
