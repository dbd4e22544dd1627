#!/usr/bin/env bash
# Penumbra's set-up on a fresh Debian 12 / Ubuntu machine: installs the Debian packages that are
# missing, builds, then runs what was asked.
#   bash scripts/bootstrap.sh cornell   # build, solve the Cornell box, render its final-gather picture
#   bash scripts/bootstrap.sh test      # build, run every test (Release, then ASan+UBSan, then the fuzzers)
#   bash scripts/bootstrap.sh bench     # build, measure the speed-accuracy trade of both Cornell scenes
#   bash scripts/bootstrap.sh build     # build only
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  cmake ninja-build g++ pkg-config python3
  libembree-dev libeigen3-dev libopenimageio-dev openimageio-tools libopenmesh-dev
  libtbb-dev nlohmann-json3-dev libcli11-dev libgtest-dev libnanoflann-dev libtinygltf-dev libtinyobjloader-dev
  libglfw3-dev libimgui-dev libgl-dev libegl-dev libgl1-mesa-dri xvfb xauth
  libbenchmark-dev gnuplot-nox clang-format libjemalloc-dev libopenexr-dev libpng-dev
  clang libclang-rt-14-dev libopenmpi-dev openmpi-bin
)

install_missing() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "bootstrap: installing ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

build() {  # build DIR [cmake args...]
  local dir=$1; shift
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DPENUMBRA_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j "$(nproc)"
}

case "${1:-}" in
  build)
    install_missing
    build build
    ;;
  cornell)
    install_missing
    build build
    ./build/bin/penumbra solve scenes/cornell-box.json --out out/cornell
    ./build/bin/penumbra render scenes/cornell-box.json --solution out/cornell --out out/cornell.exr
    echo "bootstrap: report out/cornell/report.json, final-gather picture out/cornell.png (linear: out/cornell.exr)"
    ;;
  bench)
    install_missing
    build build
    for scene in cornell-box cornell-glass; do
      ./build/bin/penumbra bench "scenes/$scene.json" --out "out/bench/$scene"
    done
    echo "bootstrap: out/bench/*/summary.md, trade.csv, error-time.png, cost-patches.png"
    ;;
  test)
    install_missing
    # The style the repository configures (.clang-format), checked before anything is built.
    git ls-files '*.cpp' '*.h' | xargs clang-format --dry-run --Werror
    echo "bootstrap: clang-format: $(git ls-files '*.cpp' '*.h' | wc -l) files follow .clang-format"
    build build
    (cd build && ctest --output-on-failure -j 2 --timeout 900)
    # The same tests, built with AddressSanitizer and UndefinedBehaviorSanitizer.
    # (GCC 12 reports false maybe-uninitialized warnings under the sanitizers: no -Werror there.)
    # -O1 -g1 (line tables, enough for the sanitizers' stack traces): measured on 2 cores, the
    # sanitizer build takes 318 s instead of 583 s at -O2 -g, its tests 1112 s instead of 1024 s.
    build build-sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPENUMBRA_SANITIZE=ON -DPENUMBRA_WERROR=OFF \
      "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
    (cd build-sanitize && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
       ctest --output-on-failure -j 2 --timeout 1800 -LE slow)
    # The scene loader and the mesh readers under libFuzzer (clang, ASan, UBSan), every input of
    # their seed corpora (tests/fuzz) and then 50,000 more from a fixed seed (10-30 s each): a
    # crash, hang, leak or runaway allocation fails.
    bash scripts/fuzz.sh --runs 50000
    ;;
  *)
    echo "usage: bash scripts/bootstrap.sh cornell|test|bench|build" >&2
    exit 2
    ;;
esac
