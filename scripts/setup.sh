#!/usr/bin/env bash
# Installs what wheelcal needs on a fresh machine with rustup: the Cortex-M4F target, the
# components CI uses, and the Debian packages for firmware size and cycle measurements.
set -euo pipefail
cd "$(dirname "$0")/.."
rustup target add thumbv7em-none-eabihf
rustup component add clippy rustfmt llvm-tools
# Optional tools (benchmarks under QEMU): only when apt is available and we are root.
if [ "${WHEELCAL_SETUP_APT:-0}" = "1" ] && command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
  apt-get update -qq
  apt-get install -y -qq qemu-system-arm binutils-arm-none-eabi
fi
# The ROS 2 bag tests write their bags with Python's rosbags (an independent writer).
python3 -m pip install --quiet --disable-pip-version-check rosbags==0.11.9
# The console's interop tests (console/tests/interop.rs) read wheelcal's MCAP files with
# the independent Python readers and its TUM files with evo.
python3 -m pip install --quiet --disable-pip-version-check \
  mcap==1.6.0 mcap-ros2-support==0.6.0 evo==1.38.1 rosbags==0.11.9
cargo fetch --locked
echo "setup done: host crates test with 'cargo test', the firmware builds with 'cargo fw'"
