#!/usr/bin/env bash
# Host benchmarks, in one run: the Rust example `bench_host` (fit time on 1e6
# samples, compensation throughput), then numpy's lstsq and scipy's lfilter on the same data
# (bench/host_baseline.py), then the table in BENCHMARKS.md (bench/host_report.py), replacing
# only the section between <!-- host-bench:start --> and <!-- host-bench:end -->.
#
#   bash bench/run-host.sh
#
# Python and its packages live in a venv under target/ (bench/ only: the crate has no Python).
# The machine should be idle: the script waits up to BENCH_QUIET_WAIT seconds (default 600)
# for the CPUs to be less than BENCH_QUIET_PCT % busy (default 15), then runs anyway and
# records how busy they were.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
venv="$root/target/bench-venv"
out="$root/target/bench-host"
numpy_version=2.4.6
scipy_version=1.17.1

# Python baseline environment (idempotent).
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  "numpy==$numpy_version" "scipy==$scipy_version"

cargo build --release --example bench_host

# Percentage of CPU time not idle over the next 2 s, all cores.
busy_pct() {
  local a b
  read -r -a a < /proc/stat
  sleep 2
  read -r -a b < /proc/stat
  local total=0 idle i
  for i in 1 2 3 4 5 6 7 8; do total=$(( total + b[i] - a[i] )); done
  idle=$(( b[4] + b[5] - a[4] - a[5] ))
  echo $(( total > 0 ? 100 * (total - idle) / total : 0 ))
}
wait_max=${BENCH_QUIET_WAIT:-600}
quiet=${BENCH_QUIET_PCT:-15}
waited=0
busy=$(busy_pct)
while [ "$busy" -ge "$quiet" ] && [ "$waited" -lt "$wait_max" ]; do
  echo "CPUs ${busy} % busy; waiting for < ${quiet} % (${waited}/${wait_max} s)" >&2
  sleep 10
  waited=$(( waited + 12 ))
  busy=$(busy_pct)
done
load_start=$(cut -d' ' -f1-3 /proc/loadavg)

mkdir -p "$out"
"$CARGO_TARGET_DIR/release/examples/bench_host" --out "$out" | tee "$out/rust.txt"
"$venv/bin/python" bench/host_baseline.py "$out" | tee "$out/python.txt"
load_end=$(cut -d' ' -f1-3 /proc/loadavg)

cpu=$(grep -m1 '^model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')
"$venv/bin/python" bench/host_report.py \
  --rust "$out/rust.txt" --python "$out/python.txt" --md BENCHMARKS.md \
  --command "bash bench/run-host.sh" \
  --info "date: $(date -u '+%Y-%m-%d %H:%M UTC'); git $(git rev-parse --short HEAD 2>/dev/null || echo '?')$(git diff --quiet HEAD -- src Cargo.toml examples/bench_host.rs 2>/dev/null || echo ' with local changes')" \
  --info "CPU: ${cpu}, $(nproc) cores; $(rustc -V); release profile (fat LTO, codegen-units 1); faer without its rayon feature (one thread)" \
  --info "baseline: Python $("$venv/bin/python" -c 'import sys; print(sys.version.split()[0])'), numpy ${numpy_version} and scipy ${scipy_version} from PyPI wheels (OpenBLAS, its default threads)" \
  --info "CPU busy before the run: ${busy} % (waited ${waited} s); load average at start ${load_start}, at end ${load_end}"
