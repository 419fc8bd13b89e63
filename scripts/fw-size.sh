#!/usr/bin/env bash
# Prints the firmware's size (llvm-size) and fails above the budget:
# flash (text + data) 128 KiB, static RAM (data + bss) 96 KiB.
set -euo pipefail
cd "$(dirname "$0")/.."
ELF="${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/release/firmware"
SIZE="$(rustc --print sysroot)/lib/rustlib/x86_64-unknown-linux-gnu/bin/llvm-size"
"$SIZE" -A "$ELF" | grep -E '^(section|\.vector_table|\.text|\.rodata|\.data|\.bss|\.uninit|Total)' || true
read -r text data bss <<<"$("$SIZE" -B "$ELF" | awk 'NR==2 {print $1, $2, $3}')"
flash=$((text + data)); ram=$((data + bss))
printf 'firmware: flash %d B (budget 131072), static RAM %d B (budget 98304)\n' "$flash" "$ram"
[ "$flash" -le 131072 ] || { echo "flash over budget"; exit 1; }
[ "$ram" -le 98304 ] || { echo "static RAM over budget"; exit 1; }
