#!/usr/bin/env bash
# The one test command (README). Runs exactly what CI runs, from a fresh machine:
# installs what it needs, then fmt, clippy -D warnings (host, and core + firmware for the
# Cortex-M4 target), host tests, firmware build and size budget, Cortex-M4 benchmarks.
set -euo pipefail
cd "$(dirname "$0")"
export CARGO_TERM_COLOR=never
TARGET=thumbv7em-none-eabihf

step() { printf '\n=== %s ===\n' "$*"; }

step "toolchain"
rustup target add "$TARGET" >/dev/null 2>&1 || rustup target add "$TARGET"
rustup component add rustfmt clippy llvm-tools >/dev/null 2>&1 || rustup component add rustfmt clippy llvm-tools
rustc --version
# flip-link: the firmware's linker (.cargo/config.toml), stack below .data/.bss.
command -v flip-link >/dev/null 2>&1 || cargo install flip-link --version 0.1.12 --locked

step "unused dependencies (cargo machete)"
command -v cargo-machete >/dev/null 2>&1 || cargo install cargo-machete --version 0.9.2 --locked
cargo machete

step "licences and bans (cargo deny; deny.toml)"
# A debug build of the tool: ≈ 2 min to install here (a release build took ≈ 7 min while
# other builds ran), and the check takes 3 s.
# Advisories are not checked: their database is on GitHub, which CI cannot reach.
command -v cargo-deny >/dev/null 2>&1 || cargo install cargo-deny --version 0.20.2 --locked --debug
cargo deny check licenses bans

step "rustfmt"
cargo fmt --all -- --check

step "clippy (host)"
cargo clippy --all-targets -- -D warnings

step "clippy (board-emu)"
# board-emu builds unicorn (C, with cmake) and its bindings (bindgen needs libclang).
if ! command -v cmake >/dev/null 2>&1 || ! ls /usr/lib/llvm-*/lib/libclang*.so* >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq && $SUDO apt-get install -y -qq cmake libclang-dev >/dev/null
fi
cargo clippy -p board-emu --all-targets --profile bench -- -D warnings

step "clippy (thumbv7em: core + firmware + bench-m4)"
RUSTFLAGS="-D warnings" cargo clippy -p hydra-core -p hydra-xy -p firmware -p bench-m4 --release --target "$TARGET" -- -D warnings
# The bring-up build (the text console instead of the framed protocol) is built too, so it
# cannot rot unseen.
RUSTFLAGS="-D warnings" cargo clippy -p firmware --release --target "$TARGET" --features console -- -D warnings
# The firmware's modules import each other in one direction only (board constants and the
# tick-link channels are leaf modules).
python3 scripts/fw-modules.py

step "host tests"
mkdir -p target # the log lives here even when CARGO_TARGET_DIR points elsewhere
# `--profile bench` (16 codegen units, no LTO: fast to link). `cargo test --release`
# would be the fat-LTO release profile since Cargo 1.57 — and would hide the class of
# x86-64 miscompile (stack-probe loops in frames > 32 KiB) that tests/tests/
# handler_big_table.rs catches.
cargo test --profile bench --no-fail-fast 2>&1 | tee target/host-tests.log | grep -E '^(test result|running|error|failures|---- )' || true
if grep -qE '^test result: FAILED|^error' target/host-tests.log || ! grep -q '^test result: ok' target/host-tests.log; then
  echo "host tests FAILED"; tail -80 target/host-tests.log; exit 1
fi
passed=$(grep -E '^test result: ok' target/host-tests.log | sed -E 's/.* ([0-9]+) passed.*/\1/' | awk '{s+=$1} END {print s+0}')
echo "host tests: $passed passed, 0 failed"

step "PLC link: pymodbus (PyPI, pinned) against the virtual board's Modbus TCP"
# A client nobody here wrote, in its own venv (the system Python stays untouched).
venv="${CARGO_TARGET_DIR:-target}/pymodbus-venv"
if ! "$venv/bin/python" -c 'import pymodbus; assert pymodbus.__version__ == "3.8.6"' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q pymodbus==3.8.6
fi
cargo build --release -q -p host-sim
if ! "$venv/bin/python" scripts/plc-modbus-test.py "${CARGO_TARGET_DIR:-target}/release/host-sim" \
  --flood-s 20 --json target/plc-modbus.json > target/plc-modbus.log 2>&1; then
  echo "pymodbus test FAILED"; tail -40 target/plc-modbus.log; exit 1
fi
echo "pymodbus: $(grep -c '^ok: ' target/plc-modbus.log) checks passed; $(tail -1 target/plc-modbus.log)"

step "firmware (release, thumbv7em)"
RUSTFLAGS="-D warnings" cargo build -p firmware --release --target "$TARGET"
./scripts/fw-size.sh

step "firmware stack (release ELF: frames <= 4 KiB, worst path leaves >= 8 KiB; no blocking logger)"
# The RTT logger is non-blocking by feature (a full buffer never masks the tick) ...
cargo tree -p firmware --target "$TARGET" -e features -i defmt-rtt | grep -q 'defmt-rtt feature "disable-blocking-mode"' \
  || { echo "defmt-rtt is not built with disable-blocking-mode"; exit 1; }
# ... and its blocking write is not linked at all (--forbid-symbol).
# (the per-function call paths: the same command without --brief)
python3 scripts/stack-check.py "${CARGO_TARGET_DIR:-target}/$TARGET/release/firmware" --brief \
  --allow-cycle rust_begin_unwind --forbid-symbol defmt_rtt::channel::Channel::blocking_write

step "board-emu: the firmware's release ELF on the emulated STM32F407, plant in the loop"
./scripts/gpl-confined.sh
cargo test -p board-emu --profile bench --no-fail-fast 2>&1 | tee target/board-emu-tests.log | grep -E '^(test |test result|running|error|---- )|rows: board|bit-exact|cuts booting' || true
if grep -qE '^test result: FAILED|^error' target/board-emu-tests.log || ! grep -q '^test result: ok' target/board-emu-tests.log; then
  echo "board-emu tests FAILED"; tail -80 target/board-emu-tests.log; exit 1
fi

step "Cortex-M4 cost (QEMU mps2-an386, budgets in bench-budget.toml)"
./bench-m4.sh

echo
echo "ci.sh: all green"
