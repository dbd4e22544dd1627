#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, AddressSanitizer, UndefinedBehaviorSanitizer) and runs each
# from a copy of its seed corpus (every input in it first); any crash, hang (10 s an input), leak or
# excess memory fails, and the input that did it is left in build-fuzz/ (crash-*, timeout-*,
# leak-*, oom-*) to become a regression input in tests/fuzz/corpus/.
#   bash scripts/fuzz.sh [SECONDS]   # explore for SECONDS (default 30) from a random seed
#   bash scripts/fuzz.sh --runs N    # N inputs from seed 1, a bounded and nearly repeatable run for
#                                    # the test command (not bit-repeatable: the inputs kept varied by
#                                    # about 10% between runs of one binary); long random runs of this
#                                    # script before a commit are what keep it from finding new faults
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ ${1:-} == --runs ]]; then
  limit=(-seed=1 -runs="$2") what="$2 inputs from seed 1"
else
  limit=(-max_total_time="${1:-30}") what="${1:-30} s"
fi
CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPENUMBRA_FUZZ=ON \
  -DPENUMBRA_TESTS=OFF "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" >/dev/null
cmake --build build-fuzz --target fuzz_scene fuzz_mesh fuzz_import fuzz_solution -j "$(nproc)"
for target in scene mesh import solution; do
  work=build-fuzz/corpus-$target
  rm -rf "$work" && mkdir -p "$work" && cp tests/fuzz/corpus/$target/* "$work"/
  (cd build-fuzz && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
     ./tests/fuzz/fuzz_$target "${limit[@]}" -timeout=10 -rss_limit_mb=2048 \
       -print_final_stats=1 "corpus-$target" 2>&1 | tail -n 40)
  echo "fuzz: fuzz_$target ran $what without a crash, hang or leak"
done
