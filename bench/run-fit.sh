#!/usr/bin/env bash
# Fit speed at shock-tube scale (issue 16, item 1), in one run: for N = 1e5 and 1e6 rows (and
# 5e6 with BENCH_FIT_5E6=1), `unlag fit est.csv -o m.toml` with default options, its wall time
# and peak memory (GNU time), then an independent numpy/scipy Steiglitz-McBride + output-error
# fit of the same order and delay on the same file (bench/fit_baseline.py), and both models'
# validation errors on another step test, computed by the same code.
#
#   bash bench/run-fit.sh
#
# Prints a Markdown table; BENCHMARKS.md holds the last one with this command.
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/fit-data.sh
sizes="1e5 1e6"
if [ "${BENCH_FIT_5E6:-0}" = 1 ]; then sizes="$sizes 5e6"; fi

echo "| rows | unlag fit (default), wall | peak memory | per sample | order / delay | numpy/scipy SM + OE, same order and delay | baseline / unlag | validation nrmse unlag | validation nrmse baseline |"
echo "|---|---|---|---|---|---|---|---|---|"
for n in $sizes; do
  dir=$(fit_data "$n")
  /usr/bin/time -f "%e %M" -o "$dir/time.txt" "$unlag" fit "$dir/est.csv" -o "$dir/m.toml" > "$dir/fit.log" 2>&1
  read -r wall kb < "$dir/time.txt"
  "$venv/bin/python" bench/fit_baseline.py fit "$dir" "$dir/m.toml" > "$dir/baseline.txt"
  get() { awk -v k="$1" '$1 == "RESULT" && $2 == k { print $3 }' "$dir/baseline.txt"; }
  base=$(get baseline_seconds)
  rows=$(python3 -c "print(int(float('$n')))")
  echo "| $n | ${wall} s | $(( kb / 1024 )) MB | $(python3 -c "print(f'{$kb * 1024 / $rows:.0f} B')") | $(get order) / $(get delay) | ${base} s | $(python3 -c "print(f'{$base / $wall:.2f}x')") | $(python3 -c "print(f'{100 * $(get unlag_val_nrmse):.4f} %')") | $(python3 -c "print(f'{100 * $(get baseline_val_nrmse):.4f} %')") |"
done
echo
echo "date: $(date -u '+%Y-%m-%d %H:%M UTC'); git $(git rev-parse --short HEAD); CPU: $(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'), $(nproc) cores; load average $(cut -d' ' -f1-3 /proc/loadavg)"
