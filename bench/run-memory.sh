#!/usr/bin/env bash
# Peak memory per sample at shock-tube scale: each streaming command on a
# 5e6-row step test and a 5e6-row validation test (written by bench/fit_baseline.py gen, the
# data of bench/run-fit.sh), wall time and peak resident memory by GNU time, as bytes per row of
# one test and as a ratio against the 100 B a row asked for and the 16 B a row the two signals
# take in f64.
#
#   bash bench/run-memory.sh          # N=5e6 by default; BENCH_MEMORY_ROWS=1e6 for a quick run
#   BENCH_MEMORY_ONLY="compensate simulate" bash bench/run-memory.sh   # only these commands' rows
#
# Prints a Markdown table; BENCHMARKS.md holds the last one with this command.
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/fit-data.sh
n="${BENCH_MEMORY_ROWS:-5e6}"
dir=$(fit_data "$n")
rows=$(python3 -c "print(int(float('$n')))")
cd "$dir"
echo "| command ($n rows a test) | wall | peak memory | per row | / 100 B budget | / 16 B (u and y in f64) |"
echo "|---|---|---|---|---|---|"
run() { # label, arguments...
  local label=$1
  shift
  if [ -n "${BENCH_MEMORY_ONLY:-}" ] && [[ " $BENCH_MEMORY_ONLY " != *" $1 "* ]]; then
    return
  fi
  /usr/bin/time -f "%e %M" -o time.txt "$unlag" "$@" > run.log 2>&1
  read -r wall kb < time.txt
  python3 - "$label" "$wall" "$kb" "$rows" <<'PY'
import sys
label, wall, kb, rows = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
per = kb * 1024 / rows
print(f"| `{label}` | {wall:.1f} s | {kb / 1024:.0f} MB | {per:.0f} B | {per / 100:.2f}x | {per / 16:.1f}x |")
PY
}
run "unlag fit est.csv -o m.toml" fit est.csv -o m.toml
# The model the other rows use, fitted untimed when the fit's row is left out.
[ -f m.toml ] || "$unlag" fit est.csv -o m.toml > /dev/null 2>&1
run "unlag compensate m.toml val.csv -o out.csv" compensate m.toml val.csv -o out.csv
run "unlag simulate m.toml val.csv -o sim.csv" simulate m.toml val.csv -o sim.csv
run "unlag compare m.toml val.csv" compare m.toml val.csv
run "unlag report m.toml est.csv val.csv -o report.html" report m.toml est.csv val.csv -o report.html
rm -f out.csv sim.csv
echo
echo "date: $(date -u '+%Y-%m-%d %H:%M UTC'); git $(git -C "$root" rev-parse --short HEAD); CPU: $(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'), $(nproc) cores"
