#!/usr/bin/env bash
# Run the prebuilt GPU benchmark with a time limit and write its markdown table to a file.
#
#   cargo build --release --example gpu_bench      # beforehand (the run needs no network)
#   tools/gpu_bench.sh OUT.md [--quick] [--budget-s S]
#
# The benchmark stops starting new cases after its budget (150 s, 100 s with --quick) and
# lists the rest as skipped; the hard limit here (GPU_BENCH_LIMIT_S, default 175 s) only
# catches a hung device. Progress goes to stderr. Exit status: the benchmark's, or 124
# when the hard limit killed it (OUT.md is then not written).
set -euo pipefail

if [ $# -lt 1 ] || [ "${1#-}" != "$1" ]; then
    echo "usage: $0 OUT.md [--quick] [--budget-s S]" >&2
    exit 2
fi
out=$1
shift
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${GPU_BENCH_BIN:-$root/target/release/examples/gpu_bench}
limit=${GPU_BENCH_LIMIT_S:-175}
if [ ! -x "$bin" ]; then
    echo "$0: $bin not found; build it first: cargo build --release --example gpu_bench" >&2
    exit 1
fi
# A CPU Vulkan driver (lavapipe) needs a runtime directory for its shader cache.
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
    export XDG_RUNTIME_DIR=${TMPDIR:-/tmp}/gpu_bench-xdg-$(id -u)
    mkdir -p -m 700 "$XDG_RUNTIME_DIR"
fi
tmp=$(mktemp "${out}.XXXXXX")
trap 'rm -f "$tmp"' EXIT
status=0
timeout -k 10 "$limit" "$bin" --out "$tmp" "$@" || status=$?
if [ "$status" -eq 124 ] || [ "$status" -eq 137 ]; then
    echo "$0: the benchmark ran past ${limit} s and was stopped" >&2
    exit 124
fi
if [ "$status" -ne 0 ]; then
    exit "$status"
fi
mv "$tmp" "$out"
trap - EXIT
cat "$out"
