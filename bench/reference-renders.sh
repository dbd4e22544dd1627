#!/usr/bin/env bash
# Renders the Cornell box and cornell-glass with the final-gather view (after one solve) and with
# the path tracer, at the scene camera's resolution, then prints a Markdown table of times and of
# the error between the two (pooled L1 after a 5x5 blur, and per region in DIR/SCENE-regions.txt). Images go to DIR (default out/reference): SCENE-final-gather.png,
# SCENE-path.png and a side-by-side SCENE-side-by-side.png (each half auto-exposed by its own
# log-average, which the two images share to within their difference).
# Usage: [REUSE_PATH=1] bash bench/reference-renders.sh [DIR] [PATH_SPP]
set -euo pipefail
cd "$(dirname "$0")/.."
exe=./build/bin/penumbra
[ -x "$exe" ] || { echo "build first: bash scripts/bootstrap.sh build" >&2; exit 1; }
dir=${1:-out/reference}
pathSpp=${2:-4096}
mkdir -p "$dir"
seconds() { sed -n 's/.* in \([0-9.e+-]*\) s$/\1/p' "$1" | tail -1; }
echo "machine: $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
echo
echo "| scene | patches | solve: form factors + specular + solve (s) | final gather, 16 spp (s) | path tracer, $pathSpp spp (s) | pooled L1 after 5x5 blur | brightness ratio |"
echo "|---|---|---|---|---|---|---|"
for scene in cornell-box cornell-glass; do
  "$exe" solve "scenes/$scene.json" --out "$dir/$scene-solve" --quiet
  "$exe" render "scenes/$scene.json" --solution "$dir/$scene-solve" --out "$dir/$scene-final-gather.exr" 2>"$dir/$scene-fg.log"
  # REUSE_PATH=1 keeps a reference already rendered (it takes minutes; it does not depend on the solve).
  if [ "${REUSE_PATH:-0}" != 1 ] || [ ! -f "$dir/$scene-path.exr" ]; then
    "$exe" render "scenes/$scene.json" --integrator path --spp "$pathSpp" --out "$dir/$scene-path.exr" 2>"$dir/$scene-path.log"
  fi
  errors=$("$exe" compare "$dir/$scene-final-gather.exr" "$dir/$scene-path.exr" --scene "scenes/$scene.json" 2>/dev/null)
  echo "$errors" > "$dir/$scene-regions.txt"
  blurred=$(echo "$errors" | sed -n 's/^pooled L1 after 5x5 box blur \([0-9.]*\) .*/\1/p')
  ratio=$(echo "$errors" | sed -n 's/.*brightness ratio \([0-9.]*\).*/\1/p')
  solve=$(python3 -c "import json,sys; s=json.load(open(sys.argv[1]))['solver']; t=s['seconds']; print(s['patches'], f\"{t['form_factors']:.1f} + {t['specular_transport']:.1f} + {t['solve']:.2f}\")" "$dir/$scene-solve/report.json")
  echo "| $scene | ${solve%% *} | ${solve#* } | $(seconds "$dir/$scene-fg.log") | $(seconds "$dir/$scene-path.log") | $blurred | $ratio |"
  oiiotool "$dir/$scene-final-gather.png" "$dir/$scene-path.png" --mosaic 2x1 -o "$dir/$scene-side-by-side.png" 2>/dev/null || true
done
echo
echo "Per region (mean ratio final gather / path, pooled L1 after the blur): $dir/*-regions.txt"
