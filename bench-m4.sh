#!/usr/bin/env bash
# What the control loop costs on a Cortex-M4F, measured without a board (docs/bench.md).
#
# Builds bench-m4 (the workspace's release profile, thumbv7em-none-eabihf), runs it twice
# on QEMU's mps2-an386 (Cortex-M4 with FPU):
#   1. `-icount shift=0`: every figure timed with SysTick, deterministic instruction counts
#      averaged over 2000 calls;
#   2. `-icount shift=0 -singlestep -d exec,nochain`: a per-instruction trace of 16 calls of
#      every figure, weighted with the Cortex-M4 cycle table (bench-m4/profile.awk) to
#      estimate cycles (an estimate: zero wait states, pipeline refill 2 cycles).
# Prints the table, writes target/bench-m4.json
#   {"<figure>": {"instructions": int, "est_cycles": int}}
# and target/bench-m4/profile.txt (where the instructions go, per source line and per
# executed instruction of follower_ff_1axis), and exits non-zero if a figure exceeds its
# budget in bench-budget.toml or has none.
#
# Needs: qemu-system-arm (installed with apt-get if missing and running as root), rustup
# target thumbv7em-none-eabihf and component llvm-tools (added if missing), awk, grep, cut.
set -euo pipefail
cd "$(dirname "$0")"

TARGET=thumbv7em-none-eabihf
TARGET_DIR="${CARGO_TARGET_DIR:-target}"
ELF="$TARGET_DIR/$TARGET/release/bench-m4"
WORK=target/bench-m4
JSON=target/bench-m4.json
BUDGET=bench-budget.toml
ANNOTATE=follower_ff_1axis
mkdir -p "$WORK"

# ---- tools ---------------------------------------------------------------------------
if ! command -v qemu-system-arm >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ]; then
    echo "bench-m4: installing qemu-system-arm" >&2
    apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-system-arm >/dev/null
  else
    echo "bench-m4: qemu-system-arm is missing (apt-get install qemu-system-arm)" >&2
    exit 1
  fi
fi
rustup target add "$TARGET" >/dev/null 2>&1 || rustup target add "$TARGET"
rustup component add llvm-tools >/dev/null 2>&1 || rustup component add llvm-tools
OBJDUMP="$(rustc --print sysroot)/lib/rustlib/x86_64-unknown-linux-gnu/bin/llvm-objdump"

# ---- build ---------------------------------------------------------------------------
cargo build -q -p bench-m4 --release --target "$TARGET"

qemu() {
  # QEMU's output always goes to a file (a closed pipe makes it spin).
  timeout 300 qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none \
    -icount shift=0 "$@" -kernel "$ELF"
}

# ---- 1. SysTick instruction counts ----------------------------------------------------
qemu -semihosting-config enable=on,target=native,arg=bench-m4 >"$WORK/measure.out" 2>&1 || {
  echo "bench-m4: the measure run failed:"; cat "$WORK/measure.out"; exit 1
}
grep -q '^DONE ok=true' "$WORK/measure.out" || {
  echo "bench-m4: the measure run reported an error:"; cat "$WORK/measure.out"; exit 1
}
grep -q '^CAL .* instr_per_tick_x1000=40000$' "$WORK/measure.out" || {
  echo "bench-m4: SysTick calibration is not 40 instructions per count (is -icount on?):"
  grep '^CAL' "$WORK/measure.out"; exit 1
}

# ---- 2. Traced profile and cycle estimate ---------------------------------------------
"$OBJDUMP" -d -C -l "$ELF" >"$WORK/disasm.txt"
# The worst-case contour point the measure run picked, traced as such.
pick="$(grep -o 'select=[0-9]*:-\?[0-9]*' "$WORK/measure.out" | head -1 | sed 's/select=//')"
profile_args="arg=bench-m4,arg=profile"
[ -n "$pick" ] && profile_args="$profile_args,arg=contour_worst=$pick"
FIFO="$WORK/trace.fifo"
rm -f "$FIFO"
mkfifo "$FIFO"
grep '^Trace' <"$FIFO" | cut -d/ -f2 >"$WORK/pcs.txt" &
reader=$!
if ! qemu -singlestep -d exec,nochain -D "$FIFO" \
  -semihosting-config "enable=on,target=native,$profile_args" >"$WORK/profile.out" 2>&1; then
  # Release the reader if QEMU never opened the FIFO.
  timeout 5 sh -c ': >"$1"' sh "$FIFO" 2>/dev/null || true
  wait "$reader" || true
  rm -f "$FIFO"
  echo "bench-m4: the profile run failed:"; cat "$WORK/profile.out"; exit 1
fi
wait "$reader" || true
rm -f "$FIFO"
awk -v annotate="$ANNOTATE" -f bench-m4/profile.awk \
  "$WORK/disasm.txt" "$WORK/pcs.txt" "$WORK/profile.out" >"$WORK/profile.txt"
rm -f "$WORK/pcs.txt"

# ---- table, JSON, budgets --------------------------------------------------------------
awk -v json="$JSON" '
  FNR == 1 { file++ }
  # bench-budget.toml: `name = instructions` lines (comments and sections ignored).
  file == 1 {
    line = $0
    sub(/#.*/, "", line)
    if (line ~ /^[ \t]*[A-Za-z0-9_]+[ \t]*=[ \t]*[0-9]+[ \t]*$/) {
      split(line, kv, "=")
      k = kv[1]; gsub(/[ \t]/, "", k)
      v = kv[2]; gsub(/[ \t]/, "", v)
      budget[k] = v + 0
    }
    next
  }
  # measure.out: FIG <name> calls= ticks= base_ticks= instr_x1000=
  file == 2 && $1 == "FIG" {
    n++
    name[n] = $2
    v = $6; sub(/instr_x1000=/, "", v)
    instr[$2] = int(v / 1000 + 0.5)
    next
  }
  # profile.txt: PROF <name> calls= instr_x1000= cycles_x1000=
  file == 3 && $1 == "PROF" {
    a = $4; sub(/instr_x1000=/, "", a)
    c = $5; sub(/cycles_x1000=/, "", c)
    tin[$2] = a / 1000
    tcy[$2] = c / 1000
    next
  }
  END {
    fail = 0
    printf "%-28s %12s %12s %10s %8s %9s  %s\n", "figure", "instructions", "est_cycles", "cyc/instr", "traced", "budget", "status"
    printf "{" > json
    for (i = 1; i <= n; i++) {
      f = name[i]
      if (!(f in tin) || tin[f] <= 0) { printf "bench-m4: no profile for %s\n", f; fail = 1; continue }
      cpi = tcy[f] / tin[f]
      est = int(instr[f] * cpi + 0.5)
      status = "ok"
      b = "-"
      if (!(f in budget)) { status = "NO BUDGET"; fail = 1 }
      else { b = budget[f]; if (instr[f] > budget[f]) { status = sprintf("OVER by %d", instr[f] - budget[f]); fail = 1 } }
      printf "%-28s %12d %12d %10.2f %8.1f %9s  %s\n", f, instr[f], est, cpi, tin[f], b, status
      printf "%s\n  \"%s\": {\"instructions\": %d, \"est_cycles\": %d}", (i > 1 ? "," : ""), f, instr[f], est > json
    }
    printf "\n}\n" > json
    close(json)
    exit fail
  }
' "$BUDGET" "$WORK/measure.out" "$WORK/profile.txt" && status=0 || status=$?

echo
echo "instructions: SysTick under -icount, averaged over 2000 calls (exact, deterministic)"
echo "est_cycles:   an ESTIMATE, instructions x cycles/instruction of the traced calls"
echo "              (Cortex-M4 TRM cycle table, zero wait states, refill P = 2)"
echo "traced:       instructions per call counted in the trace (a cross-check of SysTick)"
echo "wrote $JSON and $WORK/profile.txt"
if [ "$status" -ne 0 ]; then
  echo "bench-m4: FAILED (a figure is over its budget in $BUDGET, or has none)"
  exit 1
fi
echo "bench-m4: all figures within budget"
