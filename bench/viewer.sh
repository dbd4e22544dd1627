#!/usr/bin/env bash
# The viewer's frames per second under Xvfb and Mesa's llvmpipe (issue 18), and the cost of a new
# view against the solve and a final gather, in one run on this machine:
#  - each scene solved with the defaults (kept in DIR/solve-SCENE; delete to solve again);
#  - `penumbra view` at 1280 x 720, 120 frames from the scene's camera: frames per second after the
#    first frame, and the scene alone drawn (ten times, each finished); with the defaults, then
#    with occlusion culling forced on (and the cells it drew of those in view) and off;
#  - for cornell-glass at 256 x 256: the viewer's frame and draw, the headless radiosity view (an
#    orbit of 36 views, 4 and 1 spp: per view), and a default final gather, against the solve's
#    stages.
# Writes DIR/viewer.md. Usage: bash bench/viewer.sh [--out DIR] [SCENE ...]
#   default: the three Cornell scenes and the building, into out/bench/viewer
set -euo pipefail
cd "$(dirname "$0")/.."
exe=./build/bin/penumbra
[ -x "$exe" ] || { echo "build first: bash scripts/bootstrap.sh build" >&2; exit 1; }
command -v xvfb-run > /dev/null || { echo "needs xvfb-run (apt-get install xvfb)" >&2; exit 1; }
dir=out/bench/viewer
if [ "${1:-}" = "--out" ]; then dir=$2; shift 2; fi
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(cornell-box cornell-textured cornell-glass building)
mkdir -p "$dir"
machine="$(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"

solved() {  # the scene's default solve, made once
  local scene=$1
  [ -f "$dir/solve-$scene/solution.bin" ] || "$exe" solve "scenes/$scene.json" --out "$dir/solve-$scene" --quiet
  echo "$dir/solve-$scene"
}
view() {  # scene, WxH, [frames, occlusion culling]: the viewer's log line with its frames per second
  "$(command -v xvfb-run)" -a -s "-screen 0 1280x720x24" "$exe" view "scenes/$1.json" --solution "$(solved "$1")" \
    --resolution "$2" --screenshot "$dir/$1-$2-${4:-auto}.png" --frames "${3:-120}" --occlusion-culling "${4:-auto}" \
    2>&1 | grep 'frames/s' || true
}

gl=$(xvfb-run -a "$exe" view scenes/cornell-box.json --solution "$(solved cornell-box)" --resolution 64x64 \
  --screenshot "$dir/gl.png" --frames 1 2>&1 | grep -m1 'view: OpenGL' | sed 's/.*view: //' || true)
rows=()
for scene in "${scenes[@]}"; do
  echo "viewer: $scene" >&2
  solved "$scene" > /dev/null
  # The default (occlusion culling above 20,000 triangles), then culling forced on and off.
  rows+=("$scene|$(view "$scene" 1280x720)|$(view "$scene" 1280x720 120 on)|$(view "$scene" 1280x720 120 off)")
done

echo "viewer: cornell-glass at 256 x 256" >&2
glass=$(solved cornell-glass)
small=$(view cornell-glass 256x256 200)
orbit4=$("$exe" render scenes/cornell-glass.json --solution "$glass" --integrator radiosity --resolution 256x256 \
  --orbit 36 --spp 4 --out "$dir/orbit4.exr" 2>&1 | grep 'orbit views' || true)
orbit1=$("$exe" render scenes/cornell-glass.json --solution "$glass" --integrator radiosity --resolution 256x256 \
  --orbit 36 --spp 1 --out "$dir/orbit1.exr" 2>&1 | grep 'orbit views' || true)
gather=$("$exe" render scenes/cornell-glass.json --solution "$glass" --resolution 256x256 \
  --out "$dir/gather.exr" 2>&1 | grep 'final-gather' || true)

python3 - "$dir" "$machine" "$gl" "$glass/report.json" "$small" "$orbit4" "$orbit1" "$gather" "${rows[@]}" <<'PY'
import json, re, sys
dir, machine, gl, report, small, orbit4, orbit1, gather, *rows = sys.argv[1:]
def number(pattern, text):
    m = re.search(pattern, text)
    return float(m.group(1)) if m else float('nan')
fps = lambda line: number(r'([0-9.]+) frames/s', line)
alone = lambda line: number(r'drawn in ([0-9.]+) ms', line)
stages = json.load(open(report))['solver']['seconds']
solve = sum(v for v in stages.values() if isinstance(v, (int, float)))
fg = number(r'in ([0-9.]+) s', gather)
views = [('viewer, a frame', 1e3 / fps(small)), ('viewer, the scene alone', alone(small)),
         ('headless radiosity view, 4 spp (orbit of 36, files written)', 1e3 * number(r'in ([0-9.]+) s$', orbit4) / 36),
         ('headless radiosity view, 1 spp (orbit of 36, files written)', 1e3 * number(r'in ([0-9.]+) s$', orbit1) / 36)]
out = [f'# The viewer under llvmpipe, and the cost of a new view (bench/viewer.sh)', '',
       f'Machine: {machine}; {gl or "OpenGL unknown"}; Xvfb.', '',
       '| scene (1280 x 720, 120 frames) | frames/s | the scene alone | occlusion culling on: frames/s, cells drawn | off: frames/s |',
       '|---|---|---|---|---|']
cells = lambda line: re.search(r'\(([0-9]+) of the ([0-9]+) cells', line)
for row in rows:
    scene, line, on, off = row.split('|', 3)
    drawn = cells(on)
    shown = f'{drawn.group(1)} of {drawn.group(2)}' if drawn else '?'
    out.append(f'| {scene} | {fps(line):.1f} | {alone(line):.1f} ms | {fps(on):.1f}, {shown} | {fps(off):.1f} |')
out += ['', f'cornell-glass at 256 x 256: the solve {solve:.3f} s (its stages), a default final gather {fg:.3f} s.', '',
        '| a new view | ms | of the solve | of a final gather |', '|---|---|---|---|']
for name, ms in views:
    out.append(f'| {name} | {ms:.2f} | {100 * ms / 1e3 / solve:.2f}% | {100 * ms / 1e3 / fg:.2f}% |')
open(f'{dir}/viewer.md', 'w').write('\n'.join(out) + '\n')
print('\n'.join(out))
PY
