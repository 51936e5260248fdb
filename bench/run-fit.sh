#!/usr/bin/env bash
# Fit speed at the sizes people record and at shock-tube scale, in one run:
#
# 1. `unlag fit examples/data/step_test_1.csv -o m.toml` (4,000 rows, default options, a fresh
#    output file), wall time of the whole command (search, compensator design, file written):
#    the median of 5 runs;
# 2. `unlag diagnose` on the README's modelling loop (two 4,000-row tests, the second-order
#    model of `unlag fit ... --order 2`): the median of 3 runs;
# 3. for N = 1e5 and 1e6 rows (and 5e6 with BENCH_FIT_5E6=1), `unlag fit est.csv -o m.toml`
#    with default options, its wall time and peak memory (GNU time), then an independent
#    numpy/scipy Steiglitz-McBride + output-error fit of the same order and delay on the same
#    file (bench/fit_baseline.py), the ratio of the two times, and both models' validation
#    errors on another step test, computed by the same code; and, for the memory bandwidth,
#    the time of one pass over the record's file (`cat` to /dev/null, warm cache).
#
#   bash bench/run-fit.sh                       # BENCH_UNLAG=path/to/unlag for another binary
#
# Prints Markdown tables; BENCHMARKS.md holds the last ones with this command.
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/fit-data.sh
unlag="${BENCH_UNLAG:-$unlag}"
sizes="1e5 1e6"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
wall() { # command...: its wall time and CPU time (user + system) in seconds (GNU time)
  /usr/bin/time -f "%e %U %S" -o "$tmp/t" "$@" > /dev/null 2>&1 || { echo "failed: $*" >&2; exit 1; }
  awk '{ printf "%s %.2f\n", $1, $2 + $3 }' "$tmp/t"
}
# The median run by wall time, as "wall s (CPU c s)".
median() { sort -g | awk '{ w[NR] = $1; c[NR] = $2 } END { i = int((NR + 1) / 2); printf "%s s (CPU %s s)", w[i], c[i] }'; }
one_pass() { # file: the time of one read of it from the page cache, in ms (the best of 5)
  cat "$1" > /dev/null
  for _ in 1 2 3 4 5; do
    t0=$(date +%s%N); cat "$1" > /dev/null; t1=$(date +%s%N)
    echo $(( (t1 - t0) / 1000 ))
  done | sort -g | head -1 | awk -v b="$(stat -c %s "$1")" '{ printf "%.1f ms (%.0f MB, %.1f GB/s)", $1 / 1000, b / 1e6, b / ($1 * 1000) }'
}
small=$(for _ in 1 2 3 4 5; do
  rm -f "$tmp/m.toml"
  wall "$unlag" fit examples/data/step_test_1.csv -o "$tmp/m.toml"
done | median)
rm -f "$tmp/loop.toml"
"$unlag" fit examples/data/step_test_1.csv examples/data/step_test_2.csv --order 2 -o "$tmp/loop.toml" > /dev/null 2>&1
loop=$(for _ in 1 2 3; do
  wall "$unlag" diagnose "$tmp/loop.toml" examples/data/step_test_1.csv examples/data/step_test_2.csv
done | median)
echo "| command | wall (median), its CPU time | target (wall) |"
echo "|---|---|---|"
echo "| \`unlag fit examples/data/step_test_1.csv -o m.toml\` (4,000 rows, default options) | ${small}, 5 runs | 0.15 s |"
echo "| \`unlag diagnose loop.toml examples/data/step_test_1.csv examples/data/step_test_2.csv\` (the README's loop, order 2) | ${loop}, 3 runs | 1 s |"
echo

if [ "${BENCH_FIT_5E6:-0}" = 1 ]; then sizes="$sizes 5e6"; fi

echo "| rows | unlag fit (default), wall | its CPU time | peak memory | per sample | order / delay | numpy/scipy SM + OE, same order and delay | baseline / unlag | validation nrmse unlag | validation nrmse baseline | one pass over the file (cat) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for n in $sizes; do
  dir=$(fit_data "$n")
  rm -f "$dir/m.toml"
  /usr/bin/time -f "%e %M %U %S" -o "$dir/time.txt" "$unlag" fit "$dir/est.csv" -o "$dir/m.toml" > "$dir/fit.log" 2>&1
  read -r wall kb user sys < "$dir/time.txt"
  "$venv/bin/python" bench/fit_baseline.py fit "$dir" "$dir/m.toml" > "$dir/baseline.txt"
  get() { awk -v k="$1" '$1 == "RESULT" && $2 == k { print $3 }' "$dir/baseline.txt"; }
  base=$(get baseline_seconds)
  rows=$(python3 -c "print(int(float('$n')))")
  echo "| $n | ${wall} s | $(python3 -c "print(f'{$user + $sys:.2f} s')") | $(( kb / 1024 )) MB | $(python3 -c "print(f'{$kb * 1024 / $rows:.0f} B')") | $(get order) / $(get delay) | ${base} s | $(python3 -c "print(f'{$base / $wall:.2f}x')") | $(python3 -c "print(f'{100 * $(get unlag_val_nrmse):.4f} %')") | $(python3 -c "print(f'{100 * $(get baseline_val_nrmse):.4f} %')") | $(one_pass "$dir/est.csv") |"
done
echo
echo "date: $(date -u '+%Y-%m-%d %H:%M UTC'); git $(git rev-parse --short HEAD); binary $unlag; CPU: $(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'), $(nproc) cores; load average $(cut -d' ' -f1-3 /proc/loadavg)"
