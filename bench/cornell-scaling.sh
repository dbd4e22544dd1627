#!/usr/bin/env bash
# Times the Cornell box solve at growing patch counts and prints a Markdown table from the
# reports (form factors, solve, peak memory). Usage: bash bench/cornell-scaling.sh [N ...]
set -euo pipefail
cd "$(dirname "$0")/.."
exe=./build/bin/penumbra
[ -x "$exe" ] || { echo "build first: bash scripts/bootstrap.sh build" >&2; exit 1; }
counts=("$@")
[ ${#counts[@]} -gt 0 ] || counts=(1000 4000 16000)
echo "machine: $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo
echo "| patches asked | patches | form factors (s) | rays | kernel evaluations | solve (s) | iterations | matrix (MiB) | peak memory (MiB) |"
echo "|---|---|---|---|---|---|---|---|---|"
for n in "${counts[@]}"; do
  out=$(mktemp -d)
  "$exe" solve scenes/cornell-box.json --out "$out" --patches "$n" --quiet
  python3 - "$out/report.json" "$n" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))["solver"]
c = r["counters"]
print(f"| {sys.argv[2]} | {r['patches']} | {r['seconds']['form_factors']:.2f} | {c['form_factors.visibility_rays']:,} | "
      f"{c['form_factors.kernel_evaluations']:,} | {r['seconds']['solve']:.3f} | {r['iterations']} | {r['matrix_mib']:.0f} | {r['peak_memory_mib']:.0f} |")
PY
  rm -rf "$out"
done
