#!/usr/bin/env bash
# The GPL-2.0 emulator engine (unicorn-engine) stays inside board-emu: no other workspace
# package links it, nothing depends on board-emu, and board-emu says it is GPL-2.0.
set -euo pipefail
cd "$(dirname "$0")/.."
fail=0
for p in hydra-core hydra-xy hydra-plant host-sim tests firmware bench-m4; do
  if cargo tree -p "$p" --target all -e normal,build,dev --prefix none 2>/dev/null | grep -qE '^(unicorn-engine|board-emu)'; then
    echo "GPL confinement: $p links unicorn-engine or board-emu"; fail=1
  fi
done
# Who depends on board-emu: only itself.
users=$(cargo tree -i board-emu --workspace --target all -e normal,build,dev --prefix none 2>/dev/null | sort -u | grep -v '^board-emu' || true)
if [ -n "$users" ]; then echo "GPL confinement: depends on board-emu: $users"; fail=1; fi
lic=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print([p["license"] for p in json.load(sys.stdin)["packages"] if p["name"]=="board-emu"][0])')
[ "$lic" = "GPL-2.0-only" ] || { echo "board-emu licence is $lic, not GPL-2.0-only"; fail=1; }
cargo tree -p board-emu --prefix none | grep -q '^unicorn-engine v' || { echo "board-emu does not link unicorn-engine?"; fail=1; }
[ $fail = 0 ] && echo "GPL confinement: unicorn-engine only in board-emu (GPL-2.0-only); nothing else links it"
exit $fail
