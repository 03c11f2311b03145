#!/usr/bin/env bash
# Every performance figure of docs/PERFORMANCE.md, measured on this machine:
#   1. the machine and the code measured (nproc, CPU model, load average, rustc, commit);
#   2. firmware: flash/RAM footprint and instructions per inference in QEMU (firmware/measure.sh);
#   3. host: the criterion benchmarks (`cargo bench`), summarised as median time and throughput.
# Usage: scripts/perf.sh [--firmware | --host]   (default: both)
# Needs for the firmware part: qemu-system-arm, binutils-arm-none-eabi.
# Benchmarks take minutes; run on a quiet machine: the load average is printed with the results.
set -euo pipefail
cd "$(dirname "$0")/.."
part=${1:-all}
case "$part" in all|--firmware|--host) ;; *) echo "usage: scripts/perf.sh [--firmware | --host]" >&2; exit 2;; esac

echo "== machine"
echo "   nproc: $(nproc)"
echo "   CPU: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1)"
echo "   load average (1/5/15 min) before: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "   $(rustc --version)"
echo "   commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)$(git diff --quiet 2>/dev/null || echo ' (modified)')"

if [ "$part" != --host ]; then
  bash firmware/measure.sh
fi

if [ "$part" != --firmware ]; then
  target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
  echo "== host benchmarks (criterion; full output in $target_dir/criterion)"
  filter() { grep -vE '^(Benchmarking|Found [0-9]+ outliers|  *[0-9]+ \([0-9.]+%\) (high|low)|$)|change:|No change|Performance has|Change within' || true; }
  cargo bench --locked -p hvs-shared --bench inference -- --noplot 2>&1 | filter
  # Host: batch predict (`hvs predict`'s path), training with the defaults, the hidden sweep.
  host_benches=()
  for f in host/benches/*.rs; do host_benches+=(--bench "$(basename "$f" .rs)"); done
  cargo bench --locked -p hvs-host "${host_benches[@]}" -- --noplot 2>&1 | filter
  echo "== summary (criterion point estimates; points/s where the benchmark sets a throughput; *_cpu_time groups count thread CPU time)"
  python3 - "$target_dir/criterion" <<'PY'
import json, os, sys
root = sys.argv[1]
rows = []
for dirpath, dirs, files in os.walk(root):
    if os.path.basename(dirpath) == "new" and "estimates.json" in files:
        est = json.load(open(os.path.join(dirpath, "estimates.json")))
        bench = json.load(open(os.path.join(dirpath, "benchmark.json")))
        # The estimate criterion prints in the middle of `time:` (slope, or mean).
        ns = (est.get("slope") or est["mean"])["point_estimate"]
        tp = bench.get("throughput") or {}
        elems = tp.get("Elements") or tp.get("elements")
        rate = f"{elems / ns * 1e9 / 1e6:10.2f} M/s" if elems else ""
        rows.append((bench["full_id"], ns, rate))
def fmt(ns):
    for unit, k in (("s", 1e9), ("ms", 1e6), ("µs", 1e3)):
        if ns >= k:
            return f"{ns / k:.3f} {unit}"
    return f"{ns:.2f} ns"
for name, ns, rate in sorted(rows):
    print(f"   {name:45s} {fmt(ns):>12s} {rate}")
PY
  echo "   load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
fi
