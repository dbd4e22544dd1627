#!/usr/bin/env bash
# The solve of one scene at growing element counts, with the defaults otherwise: stage times, rays,
# the transport's storage and peak memory from each report, and each size's large surfaces (2 m^2 or
# more) against the largest size's. Writes DIR/scaling.csv, DIR/scaling.md and DIR/scaling.png
# (storage, rays and seconds against patches, log-log, beside an n log n line through the first size).
# Usage: bash bench/scaling.sh [--out DIR] [SCENE [N ...]]
#   default: scenes/building.json at 13,000 to 200,000 patches asked, into out/bench/scaling
set -euo pipefail
cd "$(dirname "$0")/.."
exe=./build/bin/penumbra
[ -x "$exe" ] || { echo "build first: bash scripts/bootstrap.sh build" >&2; exit 1; }
dir=out/bench/scaling
if [ "${1:-}" = "--out" ]; then dir=$2; shift 2; fi
scene=${1:-scenes/building.json}
[ $# -gt 0 ] && shift
counts=("$@")
[ ${#counts[@]} -gt 0 ] || counts=(3000 25000 50000 100000 200000)
mkdir -p "$dir"
machine="$(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
reports=()
for n in "${counts[@]}"; do
  out="$dir/solve-$n"
  echo "scaling: $scene at --patches $n" >&2
  "$exe" solve "$scene" --out "$out" --patches "$n" --quiet
  reports+=("$out/report.json")
done
python3 - "$dir" "$scene" "$machine" "${reports[@]}" <<'PY'
import json, math, sys
dir, scene, machine, files = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
reports = [json.load(open(f)) for f in files]
finest = max(reports, key=lambda r: r["solver"]["patches"])["objects"]
def surfaces(objects):
    errs = []
    for name, o in objects.items():
        if o["area_m2"] < 2 or sum(o["emitted_power_w"]) > 0: continue
        ref = sum(finest[name]["radiosity_mean"])
        if ref > 0: errs.append(abs(sum(o["radiosity_mean"]) / ref - 1))
    errs.sort()
    return errs
rows = []
for r in reports:
    s, c = r["solver"], r["solver"]["counters"]
    errs = surfaces(r["objects"])
    rows.append(dict(patches=s["patches"], method=s.get("form_factors", ""), meshing=s["seconds"]["meshing"],
                     form_factors=s["seconds"]["form_factors"], solve=s["seconds"]["solve"],
                     vertices=s["seconds"]["vertex_radiosity"], seconds=sum(s["seconds"].values()),
                     cast_rays=c["form_factors.cast_rays"], visibility_rays=c["form_factors.visibility_rays"],
                     rays=c["rays.nearest"] + c["rays.occlusion"], storage_mib=s["matrix_mib"],
                     peak_mib=s["peak_memory_mib"], surfaces=len(errs),
                     median=errs[len(errs) // 2] if errs else 0, worst=errs[-1] if errs else 0))
rows.sort(key=lambda x: x["patches"])
keys = list(rows[0].keys())
with open(f"{dir}/scaling.csv", "w") as f:
    f.write(",".join(keys) + "\n")
    for x in rows: f.write(",".join(str(x[k]) for k in keys) + "\n")
n0 = rows[0]["patches"]
nlogn = lambda n: n * math.log(n) / (n0 * math.log(n0))
lines = [f"# {scene}: the solve at growing element counts", "", f"Machine: {machine}, no GPU, shared.", "",
         "| patches | form factors | stages (s): meshing + form factors + solve + vertices | rays cast (M) | of which visibility (M) | storage (MiB) | peak (MiB) | rays / (n log n), first = 1 | storage / (n log n) | large surfaces vs the finest: median, worst |",
         "|---|---|---|---|---|---|---|---|---|---|"]
for x in rows:
    lines.append(f"| {x['patches']:,} | {x['method']} | {x['meshing']:.2f} + {x['form_factors']:.2f} + {x['solve']:.2f} + {x['vertices']:.2f} = {x['seconds']:.2f} | "
                 f"{x['rays'] / 1e6:.1f} | {x['visibility_rays'] / 1e6:.1f} | {x['storage_mib']:.1f} | {x['peak_mib']:.0f} | "
                 f"{x['rays'] / rows[0]['rays'] / nlogn(x['patches']):.2f} | {x['storage_mib'] / rows[0]['storage_mib'] / nlogn(x['patches']):.2f} | "
                 f"{100 * x['median']:.2f}%, {100 * x['worst']:.2f}% ({x['surfaces']}) |")
open(f"{dir}/scaling.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
with open(f"{dir}/scaling.dat", "w") as f:
    f.write("# patches storage_mib rays_m seconds nlogn_storage nlogn_rays nlogn_seconds\n")
    for x in rows:
        g = nlogn(x["patches"])
        f.write(f"{x['patches']} {x['storage_mib']} {x['rays'] / 1e6} {x['seconds']} {rows[0]['storage_mib'] * g} "
                f"{rows[0]['rays'] / 1e6 * g} {rows[0]['seconds'] * g}\n")
PY
if command -v gnuplot >/dev/null; then
  gnuplot <<EOF || echo "scaling: gnuplot failed; the table and csv are written" >&2
set terminal pngcairo size 900,560 noenhanced
set output '$dir/scaling.png'
set logscale xy
set grid
set key left top
set xlabel 'patches'
set title "$(basename "$scene"): storage, rays and time of the default solve against patches ($machine)"
plot '$dir/scaling.dat' u 1:2 w lp pt 7 lc 1 t 'storage (MiB)', '' u 1:5 w l dt 2 lc 1 t 'n log n', \
     '' u 1:3 w lp pt 5 lc 2 t 'rays (millions)', '' u 1:6 w l dt 2 lc 2 t 'n log n', \
     '' u 1:4 w lp pt 9 lc 3 t 'solve stages (s)', '' u 1:7 w l dt 2 lc 3 t 'n log n'
EOF
fi
echo "scaling: $dir/scaling.md, scaling.csv, scaling.png" >&2
