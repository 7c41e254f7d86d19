#!/usr/bin/env bash
# Fails if the release firmware contains core::fmt's float formatting (flt2dec, Grisu,
# Dragon4, float Display/Debug). One `f32::clamp` (its panic message formats the bounds)
# pulled in ~15 KB of it; a panic path, an `{}` of a float or an `expect` on a float
# computation brings it back. Run after `cargo fw`.
set -euo pipefail
cd "$(dirname "$0")/.."
elf=${1:-target/thumbv7em-none-eabihf/release/wheelcal-firmware}
[ -f "$elf" ] || { echo "$elf not found: build it with cargo fw"; exit 1; }
nm=$(find "$(rustc --print sysroot)"/lib/rustlib/*/bin -name llvm-nm -type f | head -n 1)
[ -n "$nm" ] || { echo "llvm-nm not found: rustup component add llvm-tools"; exit 1; }
# Demangled names: core::num::flt2dec::*, core::fmt::float::*, and the float impls of
# Display/Debug/LowerExp/UpperExp.
pattern='flt2dec|core::fmt::float|float_to_decimal|float_to_exponential|grisu|dragon|(Display|Debug|LowerExp|UpperExp) for f(32|64)'
hits=$("$nm" -C "$elf" | grep -E "$pattern" || true)
if [ -n "$hits" ]; then
  echo "float formatting in $elf ($(echo "$hits" | wc -l) symbols):"
  echo "$hits" | head -n 20
  echo "find the caller: a float in a panic message (clamp, expect, assert) or a {} of a float"
  exit 1
fi
echo "no float formatting in $elf"
