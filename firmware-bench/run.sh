#!/usr/bin/env bash
# Instruction count of one firmware-app control tick (four DC wheels) on a Cortex-M4F,
# under QEMU's mps2-an386 with every executed instruction traced (measuring.md).
# Needs qemu-system-arm (Debian package; WHEELCAL_SETUP_APT=1 bash scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")"
target=${CARGO_TARGET_DIR:-../target}/bench
CARGO_TARGET_DIR=$target cargo build --release --locked --target thumbv7em-none-eabihf -q
elf=$target/thumbv7em-none-eabihf/release/firmware-bench
nm=$(find "$(rustc --print sysroot)" -name llvm-nm -type f | head -n 1)
mark=$("$nm" "$elf" | awk '$3 == "bench_mark" { print $1 }')
n=$(grep -oP 'pub const N: u32 = \K[0-9]+' src/main.rs)
[ -n "$mark" ] || { echo "bench_mark not found in $elf"; exit 1; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkfifo "$tmp/exec.log"
# The trace is streamed through a FIFO into awk: ~10 million lines never touch the disk.
awk -v mark="$mark" -v n="$n" '
  BEGIN { mark = tolower(mark); sub(/^0+/, "", mark) }
  /^Trace/ {
    split($0, f, "["); split(f[2], g, "/"); pc = g[2]; sub(/^0+/, "", pc)
    if (pc == mark) { seen++; at[seen] = count }
    count++
  }
  END {
    if (seen < 5) { print "markers not found (" seen ")"; exit 1 }
    plant = at[3] - at[2]
    report("translating", at[2] - at[1] - plant)
    report("turning", at[5] - at[4] - plant)
    if (seen < 15) { print "span markers not found (" seen ")"; exit 1 }
    empty = at[11] - at[10]
    span("ReadLog of a 992-byte chunk (last request byte: decode, read, encode ~1 KiB)", at[7] - at[6] - empty)
    span("telemetry frame", at[9] - at[8] - empty)
    span("Signal signal + try_take (two critical sections)", at[13] - at[12] - empty)
    if (seen >= 15) span("save item through a Channel: try_send + try_receive (two critical sections, each copying the item)", at[15] - at[14] - empty)
    if (seen >= 17) printf "turn-law step of a differential drive'"'"'s odometry (a law stored), per tick, with its loop: %.0f instructions\n", (at[17] - at[16]) / n
    if (seen >= 19) printf "law step with the turn, speed and acceleration laws stored, per tick, with its loop: %.0f instructions\n", (at[19] - at[18]) / n
    if (seen >= 21) printf "turn-law step of an omni robot'"'"'s odometry (a law stored), per tick, with its loop: %.0f instructions\n", (at[21] - at[20]) / n
  }
  function span(what, n) {
    printf "lock span, %s: %d instructions = %.2f us to %.2f us at 168 MHz\n", what, n, n / 168, n * 1.5 / 168
  }
  function report(what, total,   per) {
    per = total / n
    printf "control tick, 4 DC wheels, %s: %.0f instructions; at 1 kHz on a 168 MHz Cortex-M4F (cycles 1-1.5x instructions): %.2f %% to %.2f %% of the CPU\n", what, per, per * 1000 / 168e6 * 100, per * 1.5 * 1000 / 168e6 * 100
  }' < "$tmp/exec.log" &
counter=$!
timeout 600 qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$elf" \
  -singlestep -d exec,nochain -D "$tmp/exec.log"
wait "$counter"
