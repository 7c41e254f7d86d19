#!/usr/bin/env bash
# Prints the release firmware's flash and static RAM use against the budgets
# (flash <= 120 KiB, static RAM <= 96 KiB including the trial log buffer).
# The ELF is read from $CARGO_TARGET_DIR when it is set (as cargo writes it there).
set -euo pipefail
cd "$(dirname "$0")/.."
elf=${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/release/wheelcal-firmware
size=$(find "$(rustc --print sysroot)" -name llvm-size -type f | head -n 1)
[ -n "$size" ] || { echo "llvm-size not found: rustup component add llvm-tools"; exit 1; }
read -r text data bss _ < <("$size" -B -d "$elf" | tail -n 1)
flash=$((text + data)); ram=$((data + bss))
awk -v e="$elf" -v f="$flash" -v r="$ram" 'BEGIN {
  printf "firmware %s\n  flash %d bytes (%.1f KiB of 120 KiB budget)\n  static RAM %d bytes (%.1f KiB of 96 KiB budget)\n", e, f, f / 1024, r, r / 1024 }'
[ "$flash" -le $((120 * 1024)) ] || { echo "flash over budget"; exit 1; }
[ "$ram" -le $((96 * 1024)) ] || { echo "RAM over budget"; exit 1; }
