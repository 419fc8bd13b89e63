#!/usr/bin/env bash
# `host-sim tune --machine` as gain scheduling (README, "Tuning the identified machine"):
# the robustness box's four softest corners (mass ×2, bulk modulus ×0.5, valve flow ×0.8
# or ×1.2, supply 120 or 180 bar) and the identification test's off-nominal machine, each
# as a machine file, tuned and checked on itself; the shipped gains on the latter for
# comparison. Prints one line per machine. Usage: scripts/tune-soft-corners.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-sim
B=target/release/host-sim
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
table="$PWD/host-sim/scenarios/tangent_table.csv"
machine() { # name supply_bar flow mass bulk [extra axis.valve lines] [extra cylinder lines]
  cat > "$dir/$1.toml" <<TOML
name = "$1"
[supply]
supply_bar = $2
[table]
file = "$table"
[[axis]]
name = "tangent"
role = "follower"
[axis.valve]
rated_flow_l_per_min = $3
$6
[axis.cylinder]
mass_kg = $4
bulk_modulus_pa = $5
$7
TOML
}
check() { grep -o 'check on .*'; }
for flow in 19.2 28.8; do # 24 l/min × 0.8, × 1.2
  for sup in 120 180; do
    name="corner_flow${flow}_supply${sup}"
    machine "$name" "$sup" "$flow" 600 0.7e9 "" ""
    printf '%-28s %s\n' "$name" "$("$B" tune --machine "$dir/$name.toml" | check)"
  done
done
machine variant 160 20.4 480 0.98e9 "bandwidth_hz = 48" "viscous_n_s_per_m = 6000
coulomb_n = 600"
printf '%-28s %s\n' "variant (tuned on itself)" "$("$B" tune --machine "$dir/variant.toml" | check)"
printf '%-28s %s\n' "variant (shipped gains)" \
  "$("$B" run "$dir/variant.toml" --json | grep -o '"max_error_um":[0-9.]*,"peak_command":[0-9.]*,"rms_error_um":[0-9.]*')"
